#pragma once

// Point-to-plane ICP between two sampled clouds (docs/methods.md §7, here
// on the voxel centroids with their normals). The descriptor matches locate keypoints only to
// about a voxel leaf (centroids of differently placed voxels), so the MSSE estimate carries
// centimetre errors; point-to-plane residuals do not depend on where a centroid lies within its
// surface patch, and refine the motion to the sensor's noise level.
//
// Data association is projective: each current point, moved by the estimate, is projected into
// the previous image (pinhole with the calibration's radial-tangential distortion), and its
// nearest previous point is sought among the previous points whose mean pixels fall in the 3 × 3
// cells of 8 × 8 pixels around it. The residuals are segmented by MSSE (scalar model, p = 6) in
// every iteration, so occluded and unmatched points are rejected without a fixed threshold.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rankslam/hal/calibration.hpp"
#include "rankslam/parallel/thread_team.hpp"
#include "rankslam/robust/workspace.hpp"

namespace rankslam::geometry {

/// A Gaussian prior on the motion ICP refines (e.g. the tracker's prediction).
struct IcpPrior {
  Eigen::Isometry3d T_previous_current = Eigen::Isometry3d::Identity();
  /// Information (symmetric) of ε = (rotation vector, translation) of T·T_previous_current⁻¹,
  /// the deviation expressed in the previous frame [rad⁻², m⁻²] (in the residuals' σ units when
  /// they are weighted); zero: no prior.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

struct IcpConfig {
  int max_iterations = 10;
  /// Current points used at most (evenly strided).
  int max_points = 1500;
  /// Associations farther than this are not made [m].
  float max_distance_m = 0.1F;
  /// MSSE κ of the residual segmentation.
  double min_inlier_fraction = 0.3;
  /// Stop when an update rotates less than this [rad] and moves less than this [m].
  double min_update = 1e-5;
  /// Points whose surface variation exceeds this take no part (0: no limit).
  float max_curvature = 0.0F;
  /// Points deeper than this in their own frame take no part (0: no limit).
  float max_depth_m = 0.0F;
  /// a of the depth noise σ = a·z² + noise_floor_m: residuals are ranked and weighted in units
  /// of it (0: plain metres, unweighted).
  float depth_noise_per_m = 0.0F;
  float noise_floor_m = 0.001F;
  /// Each step minimises the residuals plus εᵀ·information·ε. Where the clouds constrain a
  /// direction, thousands of residuals outweigh a weak prior; where they do not (one plane leaves
  /// its in-plane shifts and the turn about its normal free) the prior holds the motion there,
  /// where the solve would otherwise follow the noise.
  IcpPrior prior;
  /// Where the data constrain a direction, a prior that disagrees with them should not pull: the
  /// residuals are re-segmented every iteration, and a prior off in a well-measured direction
  /// wins by dropping the points that contradict it (simulated corridor, a feature estimate 3.3°
  /// off held the ICP 1.6° off with half its inliers). Each step splits the prior along the
  /// generalised eigenvectors of (data information, prior information), λ the data's share of a
  /// direction over the prior's, and keeps it there with weight τ/(τ+λ), τ = this value: whole
  /// where the data say nothing, a 1/(1+λ/τ) fraction where they speak. 0: the whole prior in
  /// every direction.
  double prior_crossover = 1.0;
};

struct IcpResult {
  bool ok = false;
  Eigen::Isometry3d T_previous_current = Eigen::Isometry3d::Identity();
  int associations = 0;  ///< pairs found in the last iteration
  int inliers = 0;       ///< MSSE inliers of the last iteration
  double rms_m = 0.0;    ///< RMS point-to-plane residual of the inliers
  int iterations = 0;
  /// What the last iteration's inliers alone fix: their Gauss-Newton information on ε (as
  /// IcpPrior::information: rotation vector then translation, in the previous frame, in the
  /// residuals' σ units when they are weighted), without the prior.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

/// One side of an ICP problem: a sampled cloud with normals and each point's mean pixel.
struct IcpCloud {
  std::span<const Eigen::Vector3f> points;
  std::span<const Eigen::Vector3f> normals;
  std::span<const Eigen::Vector2f> pixels;
  std::span<const float> curvature;  ///< surface variation per point (empty: all usable)
};

/// The part of a prior's information (positive definite) that IcpConfig::prior_crossover keeps
/// next to the data's: see there. Exposed for tests.
[[nodiscard]] Eigen::Matrix<double, 6, 6> prior_where_data_are_weak(const Eigen::Matrix<double, 6, 6>& data_information,
                                                                    const Eigen::Matrix<double, 6, 6>& prior_information,
                                                                    double crossover);

class PlaneIcp {
 public:
  /// Set-up (allocates): clouds of up to max_points, images of the calibration's size.
  /// With a team, the associations are searched on all its threads (the same associations).
  [[nodiscard]] std::string configure(const hal::CameraCalibration& calibration, int max_points,
                                      parallel::ThreadTeam* team = nullptr);
  [[nodiscard]] bool configured() const { return capacity_ > 0; }

  /// Per frame, no allocation: refines T_previous_current from `initial`.
  IcpResult refine(const IcpCloud& previous, const IcpCloud& current,
                   const Eigen::Isometry3d& initial, const IcpConfig& config);

  /// Per frame, no allocation: associations of `current` moved by T (as in refine, with the
  /// config's point limits) whose point-to-plane residual is at most max_residual_m.
  int count_within(const IcpCloud& previous, const IcpCloud& current, const Eigen::Isometry3d& T,
                   const IcpConfig& config, float max_residual_m);

  /// Pixel of a camera-frame point (z > 0) under the calibration's distortion model.
  [[nodiscard]] Eigen::Vector2f project(const Eigen::Vector3f& p) const;

 private:
  void index_previous(const IcpCloud& previous);
  int associate(const IcpCloud& previous, const IcpCloud& current, const Eigen::Isometry3d& T,
                int stride, float max_distance_m, const IcpConfig& config);

  hal::CameraCalibration calibration_;
  int capacity_ = 0;
  float max_curvature_ = 0.0F;
  float max_depth_ = 0.0F;
  int cells_x_ = 0;
  int cells_y_ = 0;
  std::vector<int> cell_start_;
  std::vector<int> cell_points_;
  std::vector<int> point_cell_;
  // Per association: current point moved by T, target point and normal, residual².
  std::vector<Eigen::Vector3f> moved_;
  std::vector<Eigen::Vector3f> target_;
  std::vector<Eigen::Vector3f> target_normal_;
  std::vector<double> squared_residuals_;  // normalised by σ² when weighting
  std::vector<float> inverse_sigma_;
  std::vector<std::uint8_t> associated_;  // per sampled current point, before packing
  parallel::ThreadTeam* team_ = nullptr;
  robust::RobustWorkspace workspace_;
};

}  // namespace rankslam::geometry
