#pragma once

// The orientation model of IS3D (thesis ch. 5, eq. 5.1; docs/methods.md §4): every point's unit
// normal is a hypothesis, residual r_{h,f} = arccos(n_h · n_f) in radians.

#include <span>

#include <Eigen/Core>

#include "rankslam/robust/status.hpp"

namespace rankslam::robust {

/// Dominant-orientation model for estimate_msse: sample size 1 (a hypothesis is one point's
/// normal). p = 1 as the thesis states ("models with one parameter", §5.3); a direction has two
/// degrees of freedom on the sphere, but with k0 in the hundreds the choice changes j − p in
/// σ_j² = Σ r² / (j − p) by well under 1 %. The refit is the (weighted) mean of the inlier
/// normals, renormalised: the least-squares direction under the chordal distance.
/// Selection ranks by 1 − cos, which orders like arccos² and avoids an arccos per point and
/// hypothesis; the exact arccos² is computed only for the chosen hypothesis.
class OrientationModel {
 public:
  using Params = Eigen::Vector3d;  ///< Unit direction.
  static constexpr int kSampleSize = 1;
  static constexpr int kParameterCount = 1;

  /// Set-up (allocates): room for up to max_points normals.
  explicit OrientationModel(int max_points);

  /// Per call, no allocation: copies the normals (3×n, each renormalised; zero-length or
  /// non-finite normals are invalid input) and optional non-negative weights for the refit.
  RobustStatus set_normals(const Eigen::Ref<const Eigen::Matrix3Xd>& normals,
                           std::span<const double> weights = {});

  [[nodiscard]] int size() const { return size_; }
  [[nodiscard]] int capacity() const { return static_cast<int>(normals_.rows()); }
  [[nodiscard]] Eigen::Vector3d normal(int i) const { return normals_.row(i).transpose(); }

  static Params default_params() { return Params::UnitZ(); }
  [[nodiscard]] bool sample_degenerate(std::span<const int> sample) const;
  [[nodiscard]] bool fit_sample(std::span<const int> sample, Params& direction) const;
  [[nodiscard]] bool fit_inliers(std::span<const int> inliers, const double* point_weights,
                                 Params& direction) const;
  void squared_residuals(const Params& direction, int begin, int count, double* out) const;
  void selection_scores(const Params& direction, int begin, int count, double* out) const;
  /// selection_scores (each multiplied by inverse_variances[i − begin] when that is not null)
  /// into out; returns how many are below `bound`. The same values in one pass (a vector at a
  /// time where the CPU has a vector target).
  int scaled_selection_scores(const Params& direction, int begin, int count,
                              const double* inverse_variances, double bound, double* out) const;
  /// Inverse of the score mapping: arccos(1 − score)².
  static double score_to_squared_residual(double score);

 private:
  Eigen::Matrix<double, Eigen::Dynamic, 3> normals_;  // column-major: x, y, z columns
  Eigen::VectorXd weights_;
  bool has_weights_ = false;
  int size_ = 0;
};

}  // namespace rankslam::robust
