#pragma once

// What MSSE and RANSAC share: the model concept, the result, and the hypothesis loop.

#include <algorithm>
#include <array>
#include <concepts>
#include <cstdint>
#include <span>

#include "rankslam/robust/random.hpp"
#include "rankslam/robust/status.hpp"
#include "rankslam/robust/workspace.hpp"

namespace rankslam::robust {

/// Largest minimal sample any model may draw (rigid needs 3).
inline constexpr int kMaxSampleSize = 8;

/// A model the robust estimators can fit. Implementations: RigidModel (3D-3D registration),
/// OrientationModel (dominant normal, IS3D) and ScalarModel (saliency segmentation, p = 0).
///
/// - `Params`: the fitted parameters (fixed size, cheap to copy); `default_params()` is a valid
///   neutral value returned on failure (identity, +z, ...), never NaN.
/// - `kSampleSize`: points per minimal sample; 0 means there is nothing to hypothesise and the
///   estimators evaluate exactly one hypothesis (the data as given).
/// - `kParameterCount`: p in MSSE's σ_j² = Σ r² / (j − p).
/// - `sample_degenerate(sample)`: cheap geometric test before fitting a minimal sample.
/// - `fit_sample(sample, params)` / `fit_inliers(indices, point_weights, params)`: closed-form
///   fits; false when degenerate. point_weights is null or indexed by point index, and multiplies
///   any weights the model holds itself.
/// - `squared_residuals(params, begin, count, out)`: r_i² for points [begin, begin + count).
template <class M>
concept RobustModel = requires(const M& model, const typename M::Params& params,
                               typename M::Params& params_out, std::span<const int> indices,
                               const double* point_weights, int begin, int count, double* out) {
  typename M::Params;
  requires M::kSampleSize >= 0 && M::kSampleSize <= kMaxSampleSize;
  requires M::kParameterCount >= 0;
  { M::default_params() } -> std::convertible_to<typename M::Params>;
  { model.size() } -> std::convertible_to<int>;
  { model.sample_degenerate(indices) } -> std::convertible_to<bool>;
  { model.fit_sample(indices, params_out) } -> std::convertible_to<bool>;
  { model.fit_inliers(indices, point_weights, params_out) } -> std::convertible_to<bool>;
  model.squared_residuals(params, begin, count, out);
};

/// Optional: a cheaper ranking score, monotonically increasing in the squared residual, used only
/// to select hypotheses (e.g. 1 − cos instead of arccos² for orientations, or r² in float).
/// Segmentation, refits and every reported value use the exact squared_residuals.
template <class M>
concept HasSelectionScores = requires(const M& model, const typename M::Params& params, int begin,
                                      int count, double* out) {
  model.selection_scores(params, begin, count, out);
};

/// True for models whose selection scores approximate r² itself, so that per-point 1/σ²
/// normalisation may scale the scores too (it does not commute with, e.g., 1 − cos).
template <class M>
concept ScoresAreSquaredResiduals = HasSelectionScores<M> && requires {
  requires M::kScoresAreSquaredResiduals;
};

/// Optional: the selection scores scaled by the per-point inverse variances (null: unscaled; only
/// ScoresAreSquaredResiduals models are given any) and counted below a bound, in one pass, with
/// the same values as selection_scores followed by the scaling.
template <class M>
concept HasScaledSelectionScores =
    HasSelectionScores<M> &&
    requires(const M& model, const typename M::Params& params, int begin, int count,
             const double* inverse_variances, double bound, double* out) {
      { model.scaled_selection_scores(params, begin, count, inverse_variances, bound, out) }
          -> std::convertible_to<int>;
    };

/// The default hypothesis gate: accepts every hypothesis.
struct AcceptAllHypotheses {
  template <class Params>
  constexpr bool operator()(const Params& /*hypothesis*/) const {
    return true;
  }
};

/// Result of one robust estimate. The spans point into the RobustWorkspace used for the call and
/// stay valid until its next use.
template <class Params>
struct [[nodiscard]] RobustResult {
  RobustStatus status = RobustStatus::kInvalidInput;
  /// The estimate (refitted on the inliers when `refined`); the model's neutral value on failure.
  Params model{};
  /// True when the final least-squares refit on the inliers succeeded; false means `model` is the
  /// best minimal-sample hypothesis (the inlier set alone was degenerate).
  bool refined = false;
  /// k*: the number of inliers (MSSE transition point, or RANSAC's count within the threshold).
  int inlier_count = 0;
  /// k0 = ⌈κ·n⌉ used for the least-k-th-order selection (MSSE only).
  int k0 = 0;
  /// Noise scale of the inliers in residual units (MSSE: σ_{k*}; RANSAC: RMS inlier residual).
  /// Dimensionless when per-point noise scales were given.
  double scale = 0.0;
  /// The selected hypothesis' k0-th smallest squared residual (MSSE only).
  double least_kth_sq_residual = 0.0;
  int hypotheses_evaluated = 0;   ///< Non-degenerate hypotheses that passed the gate.
  int degenerate_samples = 0;     ///< Minimal samples rejected as degenerate.
  int gated_hypotheses = 0;       ///< Hypotheses rejected by the caller's gate.
  std::span<const int> inliers;   ///< Indices of the k* inliers, ascending residual.
  std::span<const int> ordered;   ///< All n indices, ascending residual of the chosen hypothesis.
  std::span<const double> sorted_sq_residuals;  ///< The n squared residuals, ascending.
  std::span<const std::uint8_t> inlier_mask;    ///< Per input point: 1 = inlier.

  [[nodiscard]] bool ok() const { return status == RobustStatus::kOk; }
};

namespace detail {

struct HypothesisCounts {
  int evaluated = 0;
  int degenerate = 0;
  int gated = 0;
};

/// Draws `size` distinct indices below n (n ≥ size) into sample: the minimal samples of every
/// estimator, so that the serial and the team's hypothesis loops draw the same samples.
inline void draw_sample(Pcg32& rng, int n, int size, int* sample) {
  for (int s = 0; s < size; ++s) {
    int candidate = 0;
    bool repeated = true;
    while (repeated) {
      candidate = static_cast<int>(rng.bounded(static_cast<std::uint32_t>(n)));
      repeated = std::find(sample, sample + s, candidate) != sample + s;
    }
    sample[s] = candidate;
  }
}

/// Draws the minimal samples, fits them, applies the gate, and hands each surviving hypothesis to
/// `visit`. Stops after `hypotheses` evaluated or `hypotheses · draws_per_hypothesis` draws.
template <RobustModel Model, class Gate, class Visit>
void for_each_hypothesis(const Model& model, int hypotheses, int draws_per_hypothesis,
                         std::uint64_t seed, const Gate& gate, HypothesisCounts& counts,
                         Visit&& visit) {
  constexpr int kSample = Model::kSampleSize;
  typename Model::Params params = Model::default_params();
  if constexpr (kSample == 0) {
    // Nothing to hypothesise: the data as given is the one hypothesis.
    if (!model.fit_sample(std::span<const int>{}, params)) {
      ++counts.degenerate;
    } else if (!gate(params)) {
      ++counts.gated;
    } else {
      ++counts.evaluated;
      visit(params);
    }
  } else {
    const int n = model.size();
    Pcg32 rng(seed);
    std::array<int, kSample> sample{};
    const std::int64_t max_draws =
        static_cast<std::int64_t>(hypotheses) * std::max(1, draws_per_hypothesis);
    for (std::int64_t draw = 0; draw < max_draws && counts.evaluated < hypotheses; ++draw) {
      draw_sample(rng, n, kSample, sample.data());
      const std::span<const int> indices(sample);
      if (model.sample_degenerate(indices) || !model.fit_sample(indices, params)) {
        ++counts.degenerate;
        continue;
      }
      if (!gate(params)) {
        ++counts.gated;
        continue;
      }
      ++counts.evaluated;
      visit(params);
    }
  }
}

/// Fills the workspace's inverse variances from per-point noise scales; false when a scale is
/// not finite and positive.
[[nodiscard]] bool fill_inverse_variances(std::span<const double> point_sigma, int n,
                                          RobustWorkspace& workspace);

/// Sorts the workspace's first n squared residuals ascending (ties by index) and writes the
/// matching point indices to its order buffer.
void sort_residuals(RobustWorkspace& workspace, int n);

/// Number of the first `count` values strictly below `bound`.
[[nodiscard]] int count_below(const double* values, int count, double bound);

/// Moves the first `count` values strictly below `bound` to the front, in their order, and
/// returns how many there are; the values after them are left unspecified.
[[nodiscard]] int keep_below(double* values, int count, double bound);

/// Number of the first `count` values at most `bound`.
[[nodiscard]] int count_at_most(const double* values, int count, double bound);

/// Multiplies values[i] by factors[i] for i < count.
void scale_values(double* values, const double* factors, int count);

/// Sets the mask of the first n points to 0, then to 1 for the first `inliers` in `order`.
void fill_mask(RobustWorkspace& workspace, int n, int inliers);

/// True when the first `inliers` points in `order` are exactly the points set in the mask.
[[nodiscard]] bool same_inlier_set(RobustWorkspace& workspace, int n, int inliers);

}  // namespace detail
}  // namespace rankslam::robust
