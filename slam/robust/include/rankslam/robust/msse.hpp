#pragma once

// MSSE — Modified Selective Statistical Estimator (Bab-Hadiashar & Suter 1999), as used
// throughout Yousif 2016 (ch. 3 eq. 3.1, ch. 4 eqs. 4.3/4.4, ch. 5, ch. 7). docs/methods.md §1.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "rankslam/parallel/thread_team.hpp"
#include "rankslam/robust/estimator.hpp"

namespace rankslam::robust {

struct MsseConfig {
  /// H: minimal-sample hypotheses evaluated (thesis ch. 3: 1000 3-point samples for rigid
  /// registration). Range [1, 10^7]. Models with an empty sample (scalar) evaluate one.
  int hypotheses = 1000;
  /// κ: assumed minimum inlier fraction; k0 = ⌈κ·n⌉ is the order statistic minimised by the
  /// least-k-th-order fit and where segmentation starts. Must stay below the true inlier
  /// fraction. The thesis states 20 % only for ROS saliency (§4.3.3) and no value for rigid
  /// registration; 0.1 is the default here because ORB/SHOT matches can hold 80–85 % outliers
  /// (κ = 0.2 is exactly at the limit for 80 %), and with 300–800 matches k0 = 30–80 still leaves
  /// k0 ≫ p = 6 for a stable first scale estimate. Use 0.2 for ROS/ROS2D saliency. Range (0, 1].
  double min_inlier_fraction = 0.1;
  /// T: transition factor of the MSSE test r_(j+1) > T·σ_j (eq. 4.4); 2.5 keeps about 99 % of
  /// normally distributed inliers. Range (0, 100].
  double transition_factor = 2.5;
  /// Seed of the hypothesis sampler; every call restarts from it, so the same input always gives
  /// the same output.
  std::uint64_t seed = 0x9e3779b97f4a7c15ULL;
  /// Draw budget: at most hypotheses × this many minimal samples are drawn, so degenerate or
  /// gated samples are replaced but an all-degenerate input still terminates. Range [1, 1000].
  int draws_per_hypothesis = 4;
  /// Step 3, the least-squares refit on all k* inliers. Off only to inspect the raw hypothesis.
  bool refit = true;
  /// Extra segment-and-refit rounds after step 3: residuals of the refitted model are sorted and
  /// segmented again (from k0) and the model refitted on the new k*, until the inlier set stops
  /// changing or this many rounds ran. The thesis refits once (0); a noisy winning hypothesis
  /// (all-inlier minimal samples are rare and noisy at 80 % outliers) otherwise cuts its
  /// segmentation short. Measured by perf_robust (50 synthetic Kinect scenes, n = 500): scenes
  /// beyond 2 mm / 0.2° at 80 % outliers 15 → 10 (plain); at 85 % 26 → 16 (plain) and 5 → 1
  /// (noise-normalised). Each round costs one sort and one refit (~20–60 µs). Range [0, 100].
  int refine_iterations = 3;

  /// Empty when every field is in range, else the name of the first offending field.
  [[nodiscard]] std::string_view validate() const {
    if (hypotheses < 1 || hypotheses > 10'000'000) return "hypotheses";
    if (!(min_inlier_fraction > 0.0 && min_inlier_fraction <= 1.0)) return "min_inlier_fraction";
    if (!(transition_factor > 0.0 && transition_factor <= 100.0)) return "transition_factor";
    if (draws_per_hypothesis < 1 || draws_per_hypothesis > 1000) return "draws_per_hypothesis";
    if (refine_iterations < 0 || refine_iterations > 100) return "refine_iterations";
    return {};
  }
};

/// MSSE scale and segmentation (step 2) on squared residuals sorted ascending: starting at
/// j = k0, grow j while r_(j+1)² ≤ T²·σ_j², σ_j² = Σ_{i≤j} r_(i)² / (j − p) (thesis eqs. 4.3,
/// 4.4), with one running sum. Returns the transition point k* (k0 ≤ k* ≤ n) and writes σ_{k*}²
/// to *sigma_sq when non-null. Requires p < k0 ≤ n.
[[nodiscard]] int msse_transition(std::span<const double> sorted_sq_residuals, int k0,
                                  int parameter_count, double transition_factor,
                                  double* sigma_sq = nullptr);

/// The same on single-precision squared residuals (image saliency: millions of values, ch. 7);
/// the running sum is kept in double.
[[nodiscard]] int msse_transition(std::span<const float> sorted_sq_residuals, int k0,
                                  int parameter_count, double transition_factor,
                                  double* sigma_sq = nullptr);

/// k0 = ⌈κ·n⌉, raised to at least p + 1 (σ_j needs j > p) and the minimal sample size.
[[nodiscard]] int msse_first_order(double min_inlier_fraction, int n, int parameter_count,
                                   int sample_size);

/// Set-up memory for sharing MSSE's step 1 among the threads of a team: the minimal samples are
/// drawn in the serial order, fitted and gated concurrently, and the hypotheses scored in one
/// contiguous share per thread; the winner is the first hypothesis with the least k0-th residual,
/// as in the serial loop, so the estimate is the same with or without the team.
template <class Params>
struct MsseTeamScratch {
  /// Set-up (allocates): room for up to max_hypotheses hypotheses of `sample_size` points over
  /// up to max_points points. A null team (or a team of one) leaves the estimates serial.
  void reserve(parallel::ThreadTeam* team_to_use, int max_hypotheses_to_hold, int sample_size,
               int max_points_to_hold) {
    team = team_to_use;
    max_hypotheses = std::max(0, max_hypotheses_to_hold);
    max_points = std::max(0, max_points_to_hold);
    const auto h = static_cast<std::size_t>(max_hypotheses);
    params.assign(h, Params{});
    samples.assign(h * static_cast<std::size_t>(std::max(1, sample_size)), 0);
    outcome.assign(h, 0);
    scores.assign(static_cast<std::size_t>(parallel::team_size(team)) * static_cast<std::size_t>(max_points), 0.0);
  }

  /// True when an estimate of `hypotheses` over n points can use the team.
  [[nodiscard]] bool usable(int hypotheses, int n) const {
    return parallel::team_size(team) > 1 && hypotheses <= max_hypotheses && n <= max_points;
  }

  parallel::ThreadTeam* team = nullptr;
  int max_hypotheses = 0;
  int max_points = 0;
  std::vector<Params, Eigen::aligned_allocator<Params>> params;
  std::vector<int> samples;
  std::vector<std::uint8_t> outcome;  // per drawn sample: 0 evaluated, 1 degenerate, 2 gated
  std::vector<double> scores;         // per thread: max_points scores
};

namespace detail {

/// The least k0-th values of a team sharing MSSE's step 1. Each thread scores its hypotheses in
/// increasing order and keeps its own least value, which bounds it strictly (a later hypothesis
/// of the thread must do better, as serially). The threads also share the least value found so
/// far: without it each thread fully evaluates its own run of ever better hypotheses, as many as
/// the serial loop does. Another thread's value bounds inclusively, since a hypothesis tying it
/// may still win on its earlier index. So the serial winner always gets through on its thread,
/// whose earlier hypotheses are all worse than it, and wins the merge: the team's estimate is
/// the serial one.
class TeamLeastKth {
 public:
  TeamLeastKth() {
    thread_kth_.fill(std::numeric_limits<double>::infinity());
    thread_best_.fill(-1);
  }

  /// The bound on `thread`'s next hypothesis: true with it in `value`, false when unbounded.
  [[nodiscard]] bool bound(int thread, double& value) const {
    const auto t = static_cast<std::size_t>(thread);
    bool bounded = thread_best_[t] >= 0;
    value = thread_kth_[t];
    const double team = std::nextafter(team_kth_.load(std::memory_order_relaxed),
                                       std::numeric_limits<double>::infinity());
    if (team < value) {
      value = team;
      bounded = true;
    }
    return bounded;
  }

  /// Records `hypothesis`, scored by `thread` below its bound, with k0-th value `kth`.
  void record(int thread, int hypothesis, double kth) {
    const auto t = static_cast<std::size_t>(thread);
    thread_kth_[t] = kth;
    thread_best_[t] = hypothesis;
    double known = team_kth_.load(std::memory_order_relaxed);
    while (kth < known && !team_kth_.compare_exchange_weak(known, kth, std::memory_order_relaxed)) {
    }
  }

  /// The winner over the first `threads` threads: least value, ties to the earlier hypothesis;
  /// -1 when no thread recorded one.
  [[nodiscard]] int winner(int threads, double& kth) const {
    int best = -1;
    kth = std::numeric_limits<double>::infinity();
    for (std::size_t t = 0; t < static_cast<std::size_t>(threads); ++t) {
      const int index = thread_best_[t];
      if (index < 0) continue;
      if (best < 0 || thread_kth_[t] < kth || (thread_kth_[t] == kth && index < best)) {
        kth = thread_kth_[t];
        best = index;
      }
    }
    return best;
  }

 private:
  std::array<double, parallel::ThreadTeam::kMaxThreads> thread_kth_{};
  std::array<int, parallel::ThreadTeam::kMaxThreads> thread_best_{};
  std::atomic<double> team_kth_{std::numeric_limits<double>::infinity()};
};

}  // namespace detail

/// MSSE (docs/methods.md §1) on any RobustModel:
///  1. least-k-th-order selection over H minimal-sample hypotheses (nth_element per hypothesis,
///     with an exact early exit: a hypothesis with fewer than k0 residuals below the best k0-th
///     value cannot win, so evaluation stops once that is certain);
///  2. one sort of the winner's residuals, then the transition point k*;
///  3. least-squares refit on the k* inliers (weighted by 1/σ_i² when point_sigma is given, times
///     any weights the model holds), then up to refine_iterations rounds of re-segmenting with the
///     refitted model and refitting. The reported inliers, scale and sorted residuals are the
///     segmentation the returned model was last fitted on (its own, once converged).
///
/// point_sigma: optional per-point noise scale (e.g. correspondence_sigmas_m for Kinect depth);
/// when given, residuals are ranked and segmented as r_i/σ_i. gate: optional predicate on a
/// hypothesis (e.g. RigidMotionGate around a wheel-odometry prediction); rejected hypotheses do
/// not count toward H. shared: optional scratch that shares step 1 among a thread team (same
/// result). Allocates nothing once `workspace` (and `shared`) hold model.size() points.
template <RobustModel Model, class Gate = AcceptAllHypotheses>
RobustResult<typename Model::Params> estimate_msse(
    const Model& model, const MsseConfig& config, RobustWorkspace& workspace,
    std::span<const double> point_sigma = {}, const Gate& gate = Gate{},
    MsseTeamScratch<typename Model::Params>* shared = nullptr) {
  using Params = typename Model::Params;
  constexpr int kP = Model::kParameterCount;
  constexpr int kSample = Model::kSampleSize;
  constexpr int kBlock = 128;  // points per early-exit check

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
  const int k0 = msse_first_order(config.min_inlier_fraction, n, kP, kSample);
  if (n < 1 || k0 > n) {
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
  result.k0 = k0;

  bool use_scores = false;
  if constexpr (ScoresAreSquaredResiduals<Model>) {
    use_scores = true;
  } else if constexpr (HasSelectionScores<Model>) {
    use_scores = inverse_variances == nullptr;
  }

  const auto evaluate = [&](const Params& hypothesis, int begin, int count, double* out) {
    if constexpr (HasSelectionScores<Model>) {
      if (use_scores) {
        model.selection_scores(hypothesis, begin, count, out);
      } else {
        model.squared_residuals(hypothesis, begin, count, out);
      }
    } else {
      model.squared_residuals(hypothesis, begin, count, out);
    }
    if (inverse_variances != nullptr) detail::scale_values(out, inverse_variances + begin, count);
  };

  // Scores of points [begin, begin + count) into out; how many are below `bound`.
  const auto score_below = [&](const Params& hypothesis, int begin, int count, double bound,
                               double* out) {
    if constexpr (HasScaledSelectionScores<Model>) {
      if (use_scores) {
        return model.scaled_selection_scores(
            hypothesis, begin, count, inverse_variances != nullptr ? inverse_variances + begin : nullptr,
            bound, out);
      }
    }
    evaluate(hypothesis, begin, count, out);
    return detail::count_below(out, count, bound);
  };

  // Step 1: least k-th order. least_kth scores a hypothesis into `scratch` and is true, with its
  // k0-th value in `kth`, unless it is certain to fall short of `bound` (when bounded): it cannot
  // have k0 values below the best so far, so its evaluation stops early. A bounded hypothesis that
  // gets through has at least k0 values below the bound, and its k0 least are among them: the
  // selection runs on those alone (often a quarter of the points), with the same result.
  const auto least_kth = [&](const Params& hypothesis, double* scratch, bool bounded, double bound,
                             double& kth) {
    int candidates = n;
    if (bounded) {
      int below = 0;
      for (int begin = 0; begin < n; begin += kBlock) {
        const int count = std::min(kBlock, n - begin);
        below += score_below(hypothesis, begin, count, bound, scratch + begin);
        if (below + (n - begin - count) < k0) return false;
      }
      candidates = detail::keep_below(scratch, n, bound);
    } else {
      (void)score_below(hypothesis, 0, n, std::numeric_limits<double>::infinity(), scratch);
    }
    std::nth_element(scratch, scratch + (k0 - 1), scratch + candidates);
    kth = scratch[k0 - 1];
    return true;
  };
  bool have_best = false;
  double best_kth = std::numeric_limits<double>::infinity();
  Params best = Model::default_params();
  detail::HypothesisCounts counts;
  bool use_team = false;
  if constexpr (kSample > 0) {
    use_team = shared != nullptr && shared->usable(config.hypotheses, n);
    if (use_team) {
      // The serial loop's draws, in batches: each batch is fitted and gated concurrently, and
      // holds no more samples than hypotheses still wanted, so no draw is made that the serial
      // loop would not make.
      Pcg32 rng(config.seed);
      const std::int64_t max_draws = static_cast<std::int64_t>(config.hypotheses) *
                                     std::max(1, config.draws_per_hypothesis);
      std::int64_t draws = 0;
      while (counts.evaluated < config.hypotheses && draws < max_draws) {
        const int batch = static_cast<int>(
            std::min<std::int64_t>(config.hypotheses - counts.evaluated, max_draws - draws));
        for (int i = 0; i < batch; ++i) {
          detail::draw_sample(rng, n, kSample, shared->samples.data() + static_cast<std::ptrdiff_t>(i) * kSample);
        }
        draws += batch;
        Params* slots = shared->params.data() + counts.evaluated;
        shared->team->for_chunks(batch, 16, [&](int begin, int end, int /*thread*/) {
          for (int i = begin; i < end; ++i) {
            const std::span<const int> indices(
                shared->samples.data() + static_cast<std::ptrdiff_t>(i) * kSample, kSample);
            Params params = Model::default_params();
            std::uint8_t outcome = 0;
            if (model.sample_degenerate(indices) || !model.fit_sample(indices, params)) {
              outcome = 1;
            } else if (!gate(params)) {
              outcome = 2;
            }
            shared->outcome[static_cast<std::size_t>(i)] = outcome;
            slots[i] = params;
          }
        });
        int kept = 0;
        for (int i = 0; i < batch; ++i) {
          switch (shared->outcome[static_cast<std::size_t>(i)]) {
            case 0: slots[kept++] = slots[i]; break;
            case 1: ++counts.degenerate; break;
            default: ++counts.gated; break;
          }
        }
        counts.evaluated += kept;
      }
      // Chunks of hypotheses go to whichever thread asks (a thread that starts late, or shares
      // its core, takes fewer); TeamLeastKth bounds their early exits and merges their winners.
      const int hypotheses = counts.evaluated;
      detail::TeamLeastKth team_kth;
      constexpr int kHypothesesPerChunk = 4;
      shared->team->for_chunks(hypotheses, kHypothesesPerChunk, [&](int first, int last, int thread) {
        double* scratch = shared->scores.data() + static_cast<std::ptrdiff_t>(thread) * shared->max_points;
        for (int h = first; h < last; ++h) {
          double bound = 0.0;
          const bool bounded = team_kth.bound(thread, bound);
          double kth = 0.0;
          if (least_kth(shared->params[static_cast<std::size_t>(h)], scratch, bounded, bound, kth)) {
            team_kth.record(thread, h, kth);
          }
        }
      });
      const int best_index = team_kth.winner(shared->team->size(), best_kth);
      if (best_index >= 0) {
        best = shared->params[static_cast<std::size_t>(best_index)];
        have_best = true;
      }
    }
  }
  if (!use_team) {
    double* scores = workspace.scores();
    detail::for_each_hypothesis(model, config.hypotheses, config.draws_per_hypothesis, config.seed,
                                gate, counts, [&](const Params& hypothesis) {
                                  double kth = 0.0;
                                  if (least_kth(hypothesis, scores, have_best, best_kth, kth)) {
                                    best_kth = kth;
                                    best = hypothesis;
                                    have_best = true;
                                  }
                                });
  }
  result.hypotheses_evaluated = counts.evaluated;
  result.degenerate_samples = counts.degenerate;
  result.gated_hypotheses = counts.gated;
  if (!have_best) {
    result.status = counts.gated > 0 ? RobustStatus::kNoHypothesis : RobustStatus::kDegenerate;
    return result;
  }

  // Step 2: scale and segmentation on the winner's sorted residuals.
  double* sq = workspace.sq_residuals();
  const int* order = workspace.order();
  double sigma_sq = 0.0;
  // Large sets (IS3D's thousands of normals, each an arc cosine) score on the team, each point
  // into its own slot: the same values.
  constexpr int kSegmentChunk = 512;
  const bool segment_on_team = use_team && n >= 2 * kSegmentChunk;
  const auto segment = [&](const Params& hypothesis) {
    const auto residuals = [&](int begin, int end, int /*thread*/) {
      model.squared_residuals(hypothesis, begin, end - begin, sq + begin);
      if (inverse_variances != nullptr) detail::scale_values(sq + begin, inverse_variances + begin, end - begin);
    };
    if (segment_on_team) {
      shared->team->for_chunks(n, kSegmentChunk, residuals);
    } else {
      residuals(0, n, 0);
    }
    detail::sort_residuals(workspace, n);
    return msse_transition(std::span<const double>(sq, static_cast<std::size_t>(n)), k0, kP,
                           config.transition_factor, &sigma_sq);
  };
  int k_star = segment(best);
  detail::fill_mask(workspace, n, k_star);
  result.least_kth_sq_residual = sq[k0 - 1];  // exact, whatever score ranked the hypotheses

  // Step 3: refit on the inliers, optionally re-segmenting with the refitted model.
  result.model = best;
  const int refits = config.refit ? 1 + config.refine_iterations : 0;
  for (int round = 0; round < refits; ++round) {
    Params refit = result.model;
    if (!model.fit_inliers(std::span<const int>(order, static_cast<std::size_t>(k_star)),
                           inverse_variances, refit)) {
      break;
    }
    result.model = refit;
    result.refined = true;
    if (round + 1 == refits) break;
    k_star = segment(refit);
    if (detail::same_inlier_set(workspace, n, k_star)) break;  // converged
    detail::fill_mask(workspace, n, k_star);
  }
  const std::span<const int> inliers(order, static_cast<std::size_t>(k_star));
  result.status = RobustStatus::kOk;
  result.inlier_count = k_star;
  result.scale = std::sqrt(sigma_sq);
  result.inliers = inliers;
  result.ordered = std::span<const int>(order, static_cast<std::size_t>(n));
  result.sorted_sq_residuals = std::span<const double>(sq, static_cast<std::size_t>(n));
  result.inlier_mask = std::span<const std::uint8_t>(workspace.mask(), static_cast<std::size_t>(n));
  return result;
}

}  // namespace rankslam::robust
