#pragma once

#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "rankslam/eval/associate.hpp"
#include "rankslam/eval/result.hpp"
#include "rankslam/eval/trajectory.hpp"

namespace rankslam::eval {

/// Summary of a set of non-negative errors, as the TUM scripts print them (numpy semantics:
/// median averages the two middle values of an even count, stddev is the population one).
struct ErrorStats {
  std::size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double stddev = 0.0;
  double min = 0.0;
  double max = 0.0;
};

/// All zero for an empty span.
[[nodiscard]] ErrorStats compute_error_stats(std::span<const double> errors);

struct AteOptions {
  /// Association window between estimate and ground-truth stamps (evaluate_ate.py default).
  double max_difference_s = kDefaultMaxDifference_s;
};

/// Absolute trajectory error as the TUM benchmark's evaluate_ate.py: associate the stamps,
/// align the estimate's positions rigidly onto the ground truth (Horn/Umeyama, no scale), and
/// measure the remaining position differences.
struct AteResult {
  ErrorStats translation_m;
  /// Maps the estimate's world frame into the ground truth's world frame (rigid).
  Eigen::Isometry3d T_gtworld_estworld = Eigen::Isometry3d::Identity();
  /// first_index into the ground truth, second_index into the estimate, sorted by stamp.
  std::vector<StampMatch> matches;
  /// Position error of each match after alignment, in the order of `matches`.
  std::vector<double> errors_m;
  /// Every estimate pose (input order), mapped through T_gtworld_estworld.
  Trajectory aligned_estimate;
};

/// Fails, with a message saying why, when either trajectory is empty or no stamps associate.
[[nodiscard]] Result<AteResult> compute_ate(const Trajectory& ground_truth,
                                            const Trajectory& estimate,
                                            const AteOptions& options = {});

struct RpeOptions {
  /// Time between the two poses of a compared pair (evaluate_rpe.py --fixed_delta --delta 1).
  double delta_s = 1.0;
  /// Largest gap between an estimate stamp and its nearest ground-truth stamp; 0 uses
  /// evaluate_rpe.py's rule: twice the median interval of the ground truth.
  double max_gt_difference_s = 0.0;
};

/// One compared pair of the relative pose error.
struct RpePair {
  double stamp_est_0_s = 0.0;
  double stamp_est_1_s = 0.0;
  double stamp_gt_0_s = 0.0;
  double stamp_gt_1_s = 0.0;
  double translation_m = 0.0;  ///< |t(E)|, not yet divided by delta
  double rotation_deg = 0.0;   ///< angle(E), not yet divided by delta
};

/// Relative pose error (drift per second) as the TUM benchmark's evaluate_rpe.py with
/// --fixed_delta, delta in seconds and every pair (no random subsampling).
struct RpeResult {
  double delta_s = 1.0;
  ErrorStats translation_m_per_s;  ///< |t(E)| / delta
  ErrorStats rotation_deg_per_s;   ///< angle(E) in degrees / delta
  std::vector<RpePair> pairs;
};

/// Pair selection follows evaluate_rpe.py exactly:
///  - both trajectories are sorted by stamp, equal stamps count once (the last one wins);
///  - for every estimate pose i, j is the estimate pose whose stamp is nearest to
///    stamp_i + delta (ties to the earlier one); the pair is dropped when j is the last pose
///    (the script's way of not running past the end, so a trajectory shorter than delta has no
///    pairs);
///  - each of the two estimate stamps takes the nearest ground-truth pose; the pair is dropped
///    when either is more than max_gt_difference_s away (default: twice the median ground-truth
///    interval). This is a nearest-neighbour lookup, not the one-to-one association of the ATE.
/// The error is the one of Sturm et al. (IROS 2012), E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q ground
/// truth, P estimate; |t(E)| is then the length of the difference of the two relative
/// translations. (evaluate_rpe.py multiplies in the other order, (P_i^-1 P_j)(Q_i^-1 Q_j)^-1,
/// which has the same rotation angle but lets the rotation error leak into the translation.)
/// Fails, with a message saying why, when there is no pair (the caller reports null), or when
/// the options are out of range.
[[nodiscard]] Result<RpeResult> compute_rpe(const Trajectory& ground_truth,
                                            const Trajectory& estimate,
                                            const RpeOptions& options = {});

/// A relative pose measured between two stamps, e.g. a loop closure between a stored key-frame
/// and a new one.
struct StampedRelativePose {
  double stamp_from_s = 0.0;
  double stamp_to_s = 0.0;
  Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
};

/// How far one measured relative pose is from the ground truth's motion between its stamps.
struct RelativePoseError {
  /// False when either stamp has no ground-truth pose within the allowed gap (no figures then).
  bool has_ground_truth = false;
  double stamp_gt_from_s = 0.0;
  double stamp_gt_to_s = 0.0;
  double translation_m = 0.0;
  double rotation_deg = 0.0;
};

/// For each measurement, E = (Q_from⁻¹ Q_to)⁻¹ · T_from_to with Q the ground-truth pose nearest
/// each stamp (the lookup and the error of compute_rpe): |t(E)| and angle(E). A stamp farther
/// than max_gt_difference_s from every ground-truth stamp leaves its measurement without figures
/// (0: twice the median ground-truth interval, as compute_rpe). Fails when the ground truth has
/// fewer than 2 poses or a pose that is not finite, or the option is out of range.
[[nodiscard]] Result<std::vector<RelativePoseError>> compute_relative_pose_errors(
    const Trajectory& ground_truth, std::span<const StampedRelativePose> measured, double max_gt_difference_s = 0.0);

struct EvalOptions {
  AteOptions ate;
  RpeOptions rpe;
};

/// What `rankslam eval GT EST` reports.
struct EvalResult {
  AteResult ate;
  std::optional<RpeResult> rpe;    ///< empty when there is no pair delta apart
  std::string rpe_missing_reason;  ///< why rpe is empty
};

/// ATE and RPE of `estimate` against `ground_truth`. Fails only when the ATE fails.
[[nodiscard]] Result<EvalResult> evaluate(const Trajectory& ground_truth,
                                          const Trajectory& estimate,
                                          const EvalOptions& options = {});

/// Human-readable "key value" lines, one figure per line, keys padded to one column:
///   pairs, ate.rmse_m, ate.mean_m, ate.median_m, ate.std_m, ate.min_m, ate.max_m,
///   rpe.delta_s, rpe.pairs, rpe.trans_{rmse,mean,median,max}_m_per_s,
///   rpe.rot_{rmse,mean,median,max}_deg_per_s — or "rpe  none (<reason>)".
[[nodiscard]] std::string format_eval_text(const EvalResult& result);

}  // namespace rankslam::eval
