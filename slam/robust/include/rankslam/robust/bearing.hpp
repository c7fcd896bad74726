#pragma once

// Absolute pose from 3D points and the bearings a central camera of any field (a 190° fisheye
// included) sees them along: P3P samples (Grunert 1841, in the form of Haralick et al. 1994) and a
// Gauss-Newton refit, as the RobustModel for MSSE/RANSAC. Points are in frame w, bearings unit
// rays in the camera frame c; the estimate is T_c_w with bearing_i ≈ normalise(T_c_w · point_i).

#include <array>
#include <span>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rankslam/robust/status.hpp"

namespace rankslam::robust {

/// The up to four camera poses T_c_w that put three points on three bearings (unit vectors).
/// Returns how many were written to `poses`; 0 for a degenerate triple. Allocates nothing.
int solve_p3p(const std::array<Eigen::Vector3d, 3>& points, const std::array<Eigen::Vector3d, 3>& bearings,
              std::array<Eigen::Isometry3d, 4>& poses);

/// P3P pose for estimate_msse / estimate_ransac: sample size 4 (three points solve, the fourth
/// picks among their up to four poses), p = 6, residual r_i = ‖normalise(T_c_w · point_i) −
/// bearing_i‖, the chord between the two directions (≈ the angle in radians when small). The refit
/// minimises the weighted squared chords by Gauss-Newton from the hypothesis.
class BearingModel {
 public:
  using Params = Eigen::Isometry3d;  ///< T_c_w
  static constexpr int kSampleSize = 4;
  static constexpr int kParameterCount = 6;

  /// Set-up (allocates): room for up to max_points correspondences.
  explicit BearingModel(int max_points);

  /// Per call, no allocation: copies the correspondences (column i of points, frame w, is seen
  /// along column i of bearings, renormalised) and optional non-negative refit weights. Zero or
  /// non-finite bearings and non-finite points are invalid input; the model is then empty.
  RobustStatus set_correspondences(const Eigen::Ref<const Eigen::Matrix3Xd>& points,
                                   const Eigen::Ref<const Eigen::Matrix3Xd>& bearings,
                                   std::span<const double> weights = {});

  [[nodiscard]] int size() const { return size_; }
  [[nodiscard]] int capacity() const { return static_cast<int>(points_.cols()); }
  [[nodiscard]] Eigen::Vector3d point(int i) const { return points_.col(i); }
  [[nodiscard]] Eigen::Vector3d bearing(int i) const { return bearings_.col(i); }

  static Params default_params() { return Params::Identity(); }
  [[nodiscard]] bool sample_degenerate(std::span<const int> sample) const;
  [[nodiscard]] bool fit_sample(std::span<const int> sample, Params& T_c_w) const;
  [[nodiscard]] bool fit_inliers(std::span<const int> inliers, const double* point_weights, Params& T_c_w) const;
  void squared_residuals(const Params& T_c_w, int begin, int count, double* out) const;
  /// Gauss-Newton information Σ JᵀJ of the chords of `inliers` at T_c_w, for the perturbation
  /// T_c_w ← exp(ξ)·T_c_w, ξ = (translation, rotation): divided by the chords' variance it is
  /// the inverse covariance of the pose.
  [[nodiscard]] Eigen::Matrix<double, 6, 6> information(const Params& T_c_w, std::span<const int> inliers) const;

 private:
  Eigen::Matrix3Xd points_;
  Eigen::Matrix3Xd bearings_;
  Eigen::VectorXd weights_;
  bool has_weights_ = false;
  int size_ = 0;
};

}  // namespace rankslam::robust
