#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/geometry/frontend.hpp"
#include "rankslam/parallel/companion.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/frame_result.hpp"
#include "rankslam/slam/motion_estimator.hpp"
#include "rankslam/slam/orb_frontend.hpp"

#include <Eigen/Geometry>

#include <span>
#include <vector>

namespace rankslam::slam {

/// The point-to-plane information of a frame's sampled cloud at `sigma_m` per fully constraining
/// direction: what an ICP-refined registration (sequential or loop closure) measured.
[[nodiscard]] Eigen::Matrix<double, 6, 6> cloud_surface_information(const geometry::GeometricFeatures& features,
                                                                     double sigma_m);

/// Registers one frame's features against another's, for tracking and for loop closure: the
/// photometric (ORB) matches with MSSE (or the baseline's RANSAC) or, in fused mode, both kinds
/// weighted by their inlier ratios (docs/methods.md §6) and refined by the geometric ICP where
/// the photometric kind fixes the motion poorly. Buffers are sized at construction; the last
/// registration's correspondences stay readable until the next.
class Registrar {
 public:
  /// Camera velocity in its own frame: angular (rad/s), then linear (m/s).
  using Velocity = Eigen::Matrix<double, 6, 1>;

  /// `camera`, `companion` and `geometric` are the loop's and must outlive the registrar; the
  /// geometric front-end is configured by the loop (fused mode only).
  Registrar(const SlamConfig& config, const camera::DepthCameraModel& camera, RobustEstimator estimator,
            const Eigen::Isometry3d& T_base_cam, bool differential_drive, parallel::Companion& companion,
            geometry::GeometricFrontend& geometric);

  /// Set-up: shares MSSE's hypotheses among the threads of `team` (see MotionEstimator).
  void share_with(parallel::ThreadTeam* team) { estimator_.share_with(team); }
  /// Set-up, fused mode: sizes the geometric matches once the geometric front-end is configured.
  void size_geometric_matches() { geometric_matches_ = geometric_.make_correspondences(); }

  /// Registers `current` against `target`: T_target_current. In fused mode the geometric
  /// features of both frames join the estimate. `predicted` is the expected T_target_current,
  /// `at_rest` is T_target_current had the camera not moved since the previous frame. Writes the
  /// counts into `result` and adds to its matching, estimation and ICP times.
  [[nodiscard]] MotionEstimate register_frames(const PhotometricFeatures& target, const Velocity& target_velocity,
                                               const PhotometricFeatures& current, const Velocity& current_velocity,
                                               FrameResult& result, const Eigen::Isometry3d& predicted,
                                               const Eigen::Isometry3d& at_rest,
                                               const geometry::GeometricFeatures* target_geometric = nullptr,
                                               const geometry::GeometricFeatures* current_geometric = nullptr,
                                               bool refine = true);

  /// The last fused registration's photometric estimate fixes the motion too poorly to go without
  /// the geometric ICP: too few inliers, or inliers that fix the rotation worse than the bound.
  [[nodiscard]] bool photometric_needs_refinement(double above_rotation_sigma_deg) const;
  /// The fused ICP refinement's prior strength (fused_icp_prior_sigma_*), as information.
  [[nodiscard]] const Eigen::Matrix<double, 6, 1>& icp_prior_information() const { return icp_prior_information_; }

  /// The last registration's correspondences (current frame's point, target frame's point, and
  /// their combined noise), photometric first.
  [[nodiscard]] std::span<const Eigen::Vector3f> source_points() const { return source_points_; }
  [[nodiscard]] std::span<const Eigen::Vector3f> target_points() const { return target_points_; }
  [[nodiscard]] std::span<const double> correspondence_sigma_m() const { return correspondence_sigma_m_; }

 private:
  /// docs/methods.md §6 over the photometric correspondences already in source_points_ /
  /// target_points_ and the `geometric_count` geometric matches already in geometric_matches_.
  [[nodiscard]] MotionEstimate fused_estimate(const geometry::GeometricFeatures& target_geometric,
                                              const Velocity& target_velocity,
                                              const geometry::GeometricFeatures& current_geometric,
                                              const Velocity& current_velocity, int geometric_count,
                                              FrameResult& result, const Eigen::Isometry3d& predicted,
                                              const Eigen::Isometry3d& at_rest, bool refine);
  /// How well the photometric estimate's inliers (the first photometric_count correspondences)
  /// fix the rotation: the largest 1σ [deg] their information leaves; infinity without an
  /// estimate.
  [[nodiscard]] double photometric_rotation_sigma_deg(const MotionEstimate& photometric,
                                                      std::size_t photometric_count) const;
  /// Whether fused mode's ICP prior is the base's drivable step combined with the feature
  /// estimate (a differential-drive base with fused_icp_base_kinematics), not the estimate alone.
  [[nodiscard]] bool icp_prior_is_drivable_step() const {
    return config_.fused.icp_base_kinematics != 0 && differential_drive_;
  }
  /// The ICP prior of fused mode where the view leaves the motion free (see
  /// SlamConfig::fused_icp_base_kinematics): `registered` tells whether `feature` is a registration.
  [[nodiscard]] geometry::IcpPrior fused_icp_prior(const Eigen::Isometry3d& at_rest, const Eigen::Isometry3d& predicted,
                                                   const MotionEstimate& feature, bool registered,
                                                   const Eigen::Matrix<double, 6, 6>& feature_information) const;
  /// `point`, seen in image row `row`, moved to the frame's mid-exposure camera pose.
  [[nodiscard]] Eigen::Vector3f rolling_shutter_corrected(const Eigen::Vector3f& point, double row,
                                                          const Velocity& velocity) const;

  const SlamConfig& config_;
  const camera::DepthCameraModel& camera_;
  /// The camera's mounting on the base (the ICP prior's drivable step).
  Eigen::Isometry3d T_base_cam_;
  /// The calibration describes a differential-drive base (SlamConfig::fused_icp_base_kinematics).
  bool differential_drive_;
  parallel::Companion& companion_;
  geometry::GeometricFrontend& geometric_;
  MutualHammingMatcher matcher_;
  MotionEstimator estimator_;
  /// The last fused registration's photometric inliers and their rotation uncertainty.
  int last_photometric_inliers_ = 0;
  double last_photometric_rotation_sigma_deg_ = 0.0;
  /// Fused mode: the geometric matches of one registration and each correspondence's kind weight.
  geometry::GeometricCorrespondences geometric_matches_;
  Eigen::Matrix<double, 6, 1> icp_prior_information_ = Eigen::Matrix<double, 6, 1>::Zero();
  std::vector<double> kind_weights_;

  std::vector<FeatureMatch> matches_;
  std::vector<Eigen::Vector3f> source_points_;
  std::vector<Eigen::Vector3f> target_points_;
  std::vector<double> correspondence_sigma_m_;
};

/// How a registration against a stored key-frame (a loop closure, a relocalisation) came out of
/// refine_on_stored_cloud.
enum class StoredRefinement {
  kNotNeeded,  ///< the features fix the motion well: their estimate stands
  kRefined,    ///< refined by ICP on the stored cloud
  kFailed,     ///< it needed refining and ICP could not fix what the features left loose
};

/// Refines, as tracking does, a registration of `current` against a stored key-frame that the
/// registrar has just made (`T_stored_current`, replaced when refined) where its photometric
/// estimate needs it (few inliers or a rotation poorly fixed, above `above_rotation_sigma_deg`):
/// point-to-plane ICP on the stored key-frame's sampled cloud, the feature estimate as a prior
/// holding what the view leaves free.
[[nodiscard]] StoredRefinement refine_on_stored_cloud(const Registrar& registrar, geometry::GeometricFrontend& geometric,
                                                      const SlamConfig& config, double above_rotation_sigma_deg,
                                                      const geometry::GeometricFeatures& stored,
                                                      const geometry::GeometricFeatures& current,
                                                      Eigen::Isometry3d& T_stored_current);

}  // namespace rankslam::slam
