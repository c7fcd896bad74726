#pragma once

#include "rankslam/dense/aligner.hpp"
#include "rankslam/slam/motion_model.hpp"
#include "rankslam/slam/tracker.hpp"

#include <array>
#include <optional>
#include <cstdint>

namespace rankslam::slam {

/// Tracking on image features (ORB), alone or fused with the geometric ones: each frame is
/// registered against a reference frame, which it becomes itself once its inliers fall below
/// `reference_min_overlap` of the reference's. When the reference gives no acceptable
/// registration, or one whose inliers fit far worse than their noise
/// (`reference_max_noise_scale`), the previous frame is tried. At a frame where the image kind
/// (colour, IR) changes, features of the old kind are extracted too, so the pose carries across.
/// Each frame's pose covariance relative to the latest key-frame is chained registration by
/// registration: it weights the sequential edge a key-frame starts.
class FeatureTracker final : public Tracker {
 public:
  /// `fused`: geometric features join each registration (docs/methods.md §6).
  FeatureTracker(const TrackerParts& parts, bool fused);

  void track(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, FrameResult& result) override;
  [[nodiscard]] TrackedFeatures features() const override;
  [[nodiscard]] Eigen::Matrix<double, 6, 6> keyframe_edge_information(const FrameResult& result) const override;
  void keyframe_stored() override;
  void correct(const Eigen::Isometry3d& correction) override;
  void relocalise(const Eigen::Isometry3d& T_world_cam, const Eigen::Matrix<double, 6, 6>& covariance,
                  FrameResult& result) override;
  void end_frame(FrameResult& result) override;

 private:
  using Matrix6d = Eigen::Matrix<double, 6, 6>;

  /// Features of one frame with its pose.
  struct TrackedFrame {
    PhotometricFeatures features;
    geometry::GeometricFeatures geometric;  ///< Fused only.
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    /// Velocity at the frame, for its rolling-shutter correction.
    Registrar::Velocity velocity = Registrar::Velocity::Zero();
    /// Covariance of the pose accumulated since the first frame (FrameResult::odom_covariance).
    Matrix6d odom_covariance = Matrix6d::Zero();
    /// Image and depth pyramids for the dense refinement (sized only when it is on).
    dense::DenseFrame dense;
  };

  /// Extracts the current frame's features into the free slot.
  void extract(const hal::RgbdFrame& frame, const cv::Mat* image, ImageSource source, bool have_depth,
               const nav::MotionPrior* prior, FrameResult& result);
  /// Registers the current frame against the reference, else the previous frame; returns the
  /// target it was accepted against (null: none) and sets new_reference_.
  [[nodiscard]] const TrackedFrame* register_current(const hal::RgbdFrame& frame, const cv::Mat* image,
                                                     ImageSource source, bool have_depth,
                                                     const nav::MotionPrior* prior, FrameResult& result);
  /// Sets current_covariance_: the frame registered against `target`, whose pose covariance
  /// relative to the latest key-frame is `target_covariance` (null: not registered, and
  /// `target_covariance` is the previous frame's).
  void chain_covariance(const TrackedFrame* target, const Matrix6d& target_covariance, const FrameResult& result);
  /// Sets odom_covariance_: the frame's pose covariance since the first frame, from the frame its
  /// pose was measured from (the registration's target, or the previous frame where the wheels
  /// carried or joined it, or the motion model extrapolated it) and that step's own covariance.
  void chain_odom_covariance(const TrackedFrame* target, const nav::MotionPrior* prior, const FrameResult& result);
  /// Dense refinement of the accepted registration of the current frame against `target`.
  void refine_dense(const TrackedFrame& target, FrameResult& result);

  TrackerParts parts_;
  const SlamConfig& config_;
  const bool fused_;
  OrbFrontend orb_;
  MotionModel motion_;
  std::optional<dense::DenseAligner> dense_;  ///< Set when config.dense_refinement is 1.

  // Reference, previous and current frame; the reference and the previous frame may be the same
  // one. Slot indices rotate instead of copying features.
  std::array<TrackedFrame, 3> frames_;
  int reference_ = -1;
  int reference_inliers_ = 0;
  int previous_ = -1;
  int current_ = -1;
  bool new_reference_ = false;
  double previous_stamp_s_ = 0.0;
  /// Features of the other image kind, at a frame where the kind switches.
  PhotometricFeatures bridge_;

  /// Information of the current frame's accepted registration where it was modelled (see
  /// MotionEstimate::information).
  Matrix6d accepted_information_ = Matrix6d::Zero();
  /// Covariances, relative to the latest key-frame, of the current, previous and reference
  /// frames' poses (right perturbation in each frame): every registration adds its own on top of
  /// its target's, so a sequential edge is as uncertain as the chain of registrations it spans.
  Matrix6d current_covariance_ = Matrix6d::Zero();
  Matrix6d previous_covariance_ = Matrix6d::Zero();
  Matrix6d reference_covariance_ = Matrix6d::Zero();
  /// The current frame's own registration covariance, in its frame.
  Matrix6d step_covariance_ = Matrix6d::Zero();
  /// The current frame became a stored key-frame (the chain restarts at it).
  bool chain_restarted_ = false;
  /// The current frame's covariance since the first frame, for FrameResult::odom_covariance.
  Matrix6d odom_covariance_ = Matrix6d::Zero();
  /// Features' predicted noise, sampled for its median (no allocation per frame).
  std::array<float, 256> median_sample_{};
};

}  // namespace rankslam::slam
