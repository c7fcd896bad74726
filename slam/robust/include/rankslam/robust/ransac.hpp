#pragma once

// Fixed-threshold RANSAC (Fischler & Bolles 1981) over the same models, minimal solvers and
// workspace as MSSE: the comparator for MSSE and the baseline pipeline's estimator.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <string_view>

#include "rankslam/robust/estimator.hpp"

namespace rankslam::robust {

struct RansacConfig {
  /// Hypotheses evaluated (fixed; no adaptive stopping, so the cost is predictable per frame).
  /// Range [1, 10^7].
  int hypotheses = 1000;
  /// Inlier threshold on the residual (not squared), in residual units: metres for RigidModel,
  /// radians for OrientationModel, dimensionless with per-point noise scales. Range (0, 10^6].
  double inlier_threshold = 0.02;
  /// Seed of the hypothesis sampler; every call restarts from it.
  std::uint64_t seed = 0x9e3779b97f4a7c15ULL;
  /// Draw budget per hypothesis (see MsseConfig::draws_per_hypothesis). Range [1, 1000].
  int draws_per_hypothesis = 4;
  /// Least-squares refit on the inliers of the best hypothesis.
  bool refit = true;

  /// Empty when every field is in range, else the name of the first offending field.
  [[nodiscard]] std::string_view validate() const {
    if (hypotheses < 1 || hypotheses > 10'000'000) return "hypotheses";
    if (!(inlier_threshold > 0.0 && inlier_threshold <= 1e6)) return "inlier_threshold";
    if (draws_per_hypothesis < 1 || draws_per_hypothesis > 1000) return "draws_per_hypothesis";
    return {};
  }
};

/// RANSAC: keep the hypothesis with the most residuals ≤ threshold (first found wins ties;
/// exact early exit once it cannot beat the best count; counted on the model's float scores where
/// it has them, like MSSE), then refit on its inliers, taken from the exact residuals. Inliers
/// are reported in ascending residual order; `scale` is their RMS residual. point_sigma and gate as
/// for estimate_msse. Allocates nothing once `workspace` holds model.size() points.
template <RobustModel Model, class Gate = AcceptAllHypotheses>
RobustResult<typename Model::Params> estimate_ransac(const Model& model,
                                                     const RansacConfig& config,
                                                     RobustWorkspace& workspace,
                                                     std::span<const double> point_sigma = {},
                                                     const Gate& gate = Gate{}) {
  using Params = typename Model::Params;
  constexpr int kSample = Model::kSampleSize;
  constexpr int kBlock = 128;

  RobustResult<Params> result;
  result.model = Model::default_params();
  const int n = model.size();
  if (!config.validate().empty()) {
    result.status = RobustStatus::kInvalidConfig;
    return result;
  }
  if (n > workspace.capacity()) {
    result.status = RobustStatus::kCapacityExceeded;
    return result;
  }
  if (n < std::max(1, kSample)) {
    result.status = RobustStatus::kTooFewPoints;
    return result;
  }
  const double* inverse_variances = nullptr;
  if (!point_sigma.empty()) {
    if (static_cast<int>(point_sigma.size()) != n ||
        !detail::fill_inverse_variances(point_sigma, n, workspace)) {
      result.status = RobustStatus::kInvalidInput;
      return result;
    }
    inverse_variances = workspace.inverse_variances();
  }
  const double threshold_sq = config.inlier_threshold * config.inlier_threshold;

  double* scores = workspace.scores();
  int best_count = -1;
  Params best = Model::default_params();
  const auto visit = [&](const Params& hypothesis) {
    int inside = 0;
    for (int begin = 0; begin < n; begin += kBlock) {
      const int count = std::min(kBlock, n - begin);
      if constexpr (ScoresAreSquaredResiduals<Model>) {
        model.selection_scores(hypothesis, begin, count, scores + begin);
      } else {
        model.squared_residuals(hypothesis, begin, count, scores + begin);
      }
      if (inverse_variances != nullptr) {
        detail::scale_values(scores + begin, inverse_variances + begin, count);
      }
      inside += detail::count_at_most(scores + begin, count, threshold_sq);
      if (inside + (n - begin - count) <= best_count) return;  // cannot beat the best count
    }
    best_count = inside;
    best = hypothesis;
  };
  detail::HypothesisCounts counts;
  detail::for_each_hypothesis(model, config.hypotheses, config.draws_per_hypothesis, config.seed,
                              gate, counts, visit);
  result.hypotheses_evaluated = counts.evaluated;
  result.degenerate_samples = counts.degenerate;
  result.gated_hypotheses = counts.gated;
  if (best_count < 0) {
    result.status = counts.gated > 0 ? RobustStatus::kNoHypothesis : RobustStatus::kDegenerate;
    return result;
  }

  double* sq = workspace.sq_residuals();
  model.squared_residuals(best, 0, n, sq);
  if (inverse_variances != nullptr) detail::scale_values(sq, inverse_variances, n);
  detail::sort_residuals(workspace, n);
  const int inlier_count = detail::count_at_most(sq, n, threshold_sq);
  detail::fill_mask(workspace, n, inlier_count);
  double sum_sq = 0.0;
  for (int i = 0; i < inlier_count; ++i) sum_sq += sq[i];

  const int* order = workspace.order();
  const std::span<const int> inliers(order, static_cast<std::size_t>(inlier_count));
  result.model = best;
  if (config.refit && inlier_count >= std::max(1, kSample)) {
    Params refit = best;
    if (model.fit_inliers(inliers, inverse_variances, refit)) {
      result.model = refit;
      result.refined = true;
    }
  }
  result.status = RobustStatus::kOk;
  result.inlier_count = inlier_count;
  result.scale = inlier_count > 0 ? std::sqrt(sum_sq / inlier_count) : 0.0;
  result.inliers = inliers;
  result.ordered = std::span<const int>(order, static_cast<std::size_t>(n));
  result.sorted_sq_residuals = std::span<const double>(sq, static_cast<std::size_t>(n));
  result.inlier_mask = std::span<const std::uint8_t>(workspace.mask(), static_cast<std::size_t>(n));
  return result;
}

}  // namespace rankslam::robust
