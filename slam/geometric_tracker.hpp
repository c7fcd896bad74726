#pragma once

#include "rankslam/slam/motion_model.hpp"
#include "rankslam/slam/tracker.hpp"

#include <array>

namespace rankslam::slam {

/// Depth-only tracking (IS3D keypoints, SHOT, MSSE, ICP: docs/methods.md §3–4): each frame is
/// registered against the last frame that had features. Sequential edges are weighted by the
/// registration's inlier count and noise scale.
class GeometricTracker final : public Tracker {
 public:
  explicit GeometricTracker(const TrackerParts& parts);

  void track(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, FrameResult& result) override;
  [[nodiscard]] TrackedFeatures features() const override;
  [[nodiscard]] Eigen::Matrix<double, 6, 6> keyframe_edge_information(const FrameResult& result) const override;
  void correct(const Eigen::Isometry3d& correction) override;
  void relocalise(const Eigen::Isometry3d& T_world_cam, const Eigen::Matrix<double, 6, 6>& covariance,
                  FrameResult& result) override;
  void end_frame(FrameResult& result) override;

 private:
  TrackerParts parts_;
  MotionModel motion_;
  std::array<geometry::GeometricFeatures, 2> features_;
  int previous_ = -1;  ///< Slot of the last frame with features.
  int current_ = 0;
  Eigen::Isometry3d T_world_previous_ = Eigen::Isometry3d::Identity();
  /// Pose of the frame whose features are previous_ (older than the previous frame when frames
  /// without features came in between).
  Eigen::Isometry3d T_world_target_ = Eigen::Isometry3d::Identity();
};

}  // namespace rankslam::slam
