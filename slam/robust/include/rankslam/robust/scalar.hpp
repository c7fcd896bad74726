#pragma once

// The zero-parameter "model" of ROS / ROS2D saliency segmentation (thesis §4.3, §7.3;
// docs/methods.md §1): the residuals are the given non-negative values themselves.

#include <cstdint>
#include <span>

#include "rankslam/robust/status.hpp"

namespace rankslam::robust {

/// How MSSE reads the given values.
enum class ScalarKind : std::uint8_t {
  /// Each value is a squared residual r² (σ_j² = Σ v / (j − p), stop when v > T²·σ_j²). The
  /// thesis' saliency measures are sums of squares: ROS θ = mean of φ² (§4.3), ROS2D
  /// r = Σ w·(I_c − I_j)² (§7.3). On flat points they behave like χ², and MSSE's Gaussian
  /// assumption holds for their square roots: a 80/20 mixture of N(0,1)² and large values splits
  /// at ≈ 99 % of the flat points, where reading them as r stops at ≈ 70 %.
  kSquaredResidual,
  /// Each value is a residual magnitude r ≥ 0.
  kResidual,
};

/// Scalar saliency values for estimate_msse: nothing to hypothesise (sample size 0, p = 0), so
/// MSSE reduces to one sort and the transition search. Group 1 (result.inliers, the first k* of
/// result.ordered) are the flat/uniform points; group 2 (result.ordered past k*) the salient
/// ones. Use MsseConfig::min_inlier_fraction = 0.2 (thesis §4.3.3). result.scale is in units
/// of r, i.e. of sqrt(value) for kSquaredResidual.
class ScalarModel {
 public:
  struct Params {};  ///< Nothing is estimated.
  static constexpr int kSampleSize = 0;
  static constexpr int kParameterCount = 0;

  explicit ScalarModel(ScalarKind kind = ScalarKind::kSquaredResidual) : kind_(kind) {}

  /// Per call, no copy: keeps a view of the values (which must outlive the estimate). Values
  /// must be finite and non-negative (they are residual magnitudes); on error the model is empty.
  RobustStatus set_values(std::span<const double> values);

  [[nodiscard]] int size() const { return static_cast<int>(values_.size()); }
  [[nodiscard]] ScalarKind kind() const { return kind_; }

  static Params default_params() { return {}; }
  [[nodiscard]] bool sample_degenerate(std::span<const int> /*sample*/) const { return false; }
  [[nodiscard]] bool fit_sample(std::span<const int> /*sample*/, Params& /*params*/) const {
    return true;
  }
  [[nodiscard]] bool fit_inliers(std::span<const int> /*inliers*/,
                                 const double* /*point_weights*/, Params& /*params*/) const {
    return true;
  }
  void squared_residuals(const Params& params, int begin, int count, double* out) const;

 private:
  ScalarKind kind_;
  std::span<const double> values_;
};

}  // namespace rankslam::robust
