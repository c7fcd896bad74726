#pragma once

#include "rankslam/parallel/thread_team.hpp"
#include "rankslam/slam/config.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>

namespace rankslam::slam {

struct MotionEstimate {
  bool ok = false;
  /// Maps source points onto target points.
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  int inliers = 0;
  /// RMS of the inliers' residuals in units of their predicted noise (the `sigma_m` given to
  /// estimate()), taken over the `inliers` smallest under the returned motion: about 1 or below
  /// while the noise model holds, larger when the registration fits worse than its matches'
  /// noise explains (blur, rolling shutter, a wrong alignment). 1 without predicted noise.
  double noise_scale = 1.0;
  /// Point-to-plane inliers of the dense refinement that set T_target_source (0: none did).
  int icp_inliers = 0;
  /// Information of T_target_source over a small motion in the source frame (see
  /// registration_support.hpp) where the registration models it; zero: not modelled (the
  /// inlier count stands for it).
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  std::string_view failure_reason;
};

/// The robust estimator behind a registration.
enum class RobustEstimator : std::uint8_t {
  kMsse,    ///< Rank-order statistics, scale found per registration (docs/methods.md §2).
  kRansac,  ///< Fixed metric threshold: the comparator the thesis measures MSSE against.
};

/// Robust rigid 3D–3D estimation with MSSE or fixed-threshold RANSAC. Workspaces are sized at
/// construction.
class MotionEstimator {
 public:
  MotionEstimator(const SlamConfig& config, RobustEstimator estimator, std::size_t max_points);
  ~MotionEstimator();
  MotionEstimator(const MotionEstimator&) = delete;
  /// Set-up (allocates): shares MSSE's hypotheses among the threads of `team` from now on (the
  /// same estimates). The team must outlive this estimator.
  void share_with(parallel::ThreadTeam* team);
  MotionEstimator& operator=(const MotionEstimator&) = delete;

  /// `sigma_m`, when not empty, is each correspondence's predicted residual noise; MSSE then
  /// ranks and segments residuals in units of their own noise and weights the refit by 1/σ².
  /// RANSAC ignores it: its fixed metric threshold is what the baseline stands for.
  /// `T_target_source_predicted` (e.g. constant velocity) arbitrates when a low inlier fraction
  /// calls for a second estimate (see the implementation). `weights`, when not empty, multiply
  /// each correspondence's refit weight: the per-kind weights W_P, W_G of the fused registration
  /// (docs/methods.md §6).
  [[nodiscard]] MotionEstimate estimate(std::span<const Eigen::Vector3f> source,
                                        std::span<const Eigen::Vector3f> target,
                                        std::span<const double> sigma_m = {},
                                        const Eigen::Isometry3d* T_target_source_predicted = nullptr,
                                        std::span<const double> weights = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rankslam::slam
