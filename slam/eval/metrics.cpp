#include "rankslam/eval/metrics.hpp"
#include "rankslam/core/lie.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <string_view>

#include <Eigen/Geometry>

namespace rankslam::eval {
namespace {

std::string seconds_text(double value_s) {
  std::array<char, 64> text{};
  std::snprintf(text.data(), text.size(), "%.6f", value_s);
  return text.data();
}

/// The span of stamps "[first, last] s" of a trajectory, for error messages.
std::string stamp_range_text(const Trajectory& trajectory) {
  double first_s = trajectory.front().stamp_s;
  double last_s = first_s;
  for (const StampedPose& pose : trajectory) {
    first_s = std::min(first_s, pose.stamp_s);
    last_s = std::max(last_s, pose.stamp_s);
  }
  // Appended, not "[" + ...: GCC 12 at -O3 reports a false -Wrestrict on the literal-first operator+.
  std::string text = "[";
  text += seconds_text(first_s);
  text += ", ";
  text += seconds_text(last_s);
  text += "] s";
  return text;
}

/// Empty when every pose is finite, otherwise names the first one that is not.
std::string non_finite_pose(const Trajectory& trajectory, std::string_view name) {
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    if (!std::isfinite(trajectory[i].stamp_s) || !trajectory[i].T_world_cam.matrix().allFinite()) {
      return std::string(name) + " pose " + std::to_string(i) + " (stamp " +
             seconds_text(trajectory[i].stamp_s) + " s) is not finite";
    }
  }
  return {};
}

/// A trajectory sorted by stamp with one pose per stamp (the last in input order), as the TUM
/// scripts see it after keying a dict by stamp.
struct SortedTrajectory {
  std::vector<double> stamps_s;
  std::vector<const Eigen::Isometry3d*> poses;
};

SortedTrajectory sort_unique(const Trajectory& trajectory) {
  std::vector<std::size_t> order;
  order.reserve(trajectory.size());
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    if (std::isfinite(trajectory[i].stamp_s)) order.push_back(i);
  }
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return trajectory[a].stamp_s < trajectory[b].stamp_s;
  });
  SortedTrajectory sorted;
  sorted.stamps_s.reserve(order.size());
  sorted.poses.reserve(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) {
    const StampedPose& pose = trajectory[order[k]];
    if (k + 1 < order.size() && trajectory[order[k + 1]].stamp_s == pose.stamp_s) continue;
    sorted.stamps_s.push_back(pose.stamp_s);
    sorted.poses.push_back(&pose.T_world_cam);
  }
  return sorted;
}

/// Index of the stamp nearest to t in an ascending, non-empty list; ties go to the earlier one.
std::size_t closest_index(const std::vector<double>& sorted_s, double t_s) {
  const auto it = std::lower_bound(sorted_s.begin(), sorted_s.end(), t_s);
  if (it == sorted_s.begin()) return 0;
  const auto after = static_cast<std::size_t>(it - sorted_s.begin());
  if (it == sorted_s.end()) return after - 1;
  return (t_s - sorted_s[after - 1] <= sorted_s[after] - t_s) ? after - 1 : after;
}

double median_of(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const std::size_t half = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(half),
                   values.end());
  const double upper = values[half];
  if (values.size() % 2 == 1) return upper;
  const double lower =
      *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(half));
  return 0.5 * (lower + upper);
}

/// The largest gap allowed between a stamp and its nearest ground-truth stamp: `requested`, or
/// for 0 evaluate_rpe.py's rule, twice the median interval of the (sorted, ≥ 2 poses) truth.
double gt_difference_or_default(const SortedTrajectory& truth, double requested_s) {
  if (requested_s != 0.0) return requested_s;
  std::vector<double> intervals_s(truth.stamps_s.size() - 1);
  for (std::size_t k = 0; k + 1 < truth.stamps_s.size(); ++k) {
    intervals_s[k] = truth.stamps_s[k + 1] - truth.stamps_s[k];
  }
  return 2.0 * median_of(std::move(intervals_s));
}

/// A motion measured between two stamps against the ground truth's motion between the poses
/// nearest them: E = (Q_0⁻¹·Q_1)⁻¹·measured (Sturm et al., IROS 2012), |t(E)| and angle(E).
/// No figures when either stamp is more than max_gap_s from its nearest ground-truth stamp.
RelativePoseError error_against_truth(const SortedTrajectory& truth, double stamp_0_s, double stamp_1_s,
                                      const Eigen::Isometry3d& measured, double max_gap_s) {
  RelativePoseError result;
  const std::size_t g0 = closest_index(truth.stamps_s, stamp_0_s);
  const std::size_t g1 = closest_index(truth.stamps_s, stamp_1_s);
  if (std::abs(truth.stamps_s[g0] - stamp_0_s) > max_gap_s || std::abs(truth.stamps_s[g1] - stamp_1_s) > max_gap_s) {
    return result;
  }
  const Eigen::Isometry3d error = (truth.poses[g0]->inverse() * *truth.poses[g1]).inverse() * measured;
  result.has_ground_truth = true;
  result.stamp_gt_from_s = truth.stamps_s[g0];
  result.stamp_gt_to_s = truth.stamps_s[g1];
  result.translation_m = error.translation().norm();
  result.rotation_deg = lie::rotation_deg(error);
  return result;
}

}  // namespace

ErrorStats compute_error_stats(std::span<const double> errors) {
  ErrorStats stats;
  stats.count = errors.size();
  if (errors.empty()) return stats;
  const auto n = static_cast<double>(errors.size());
  double sum = 0.0;
  double sum_squares = 0.0;
  stats.min = errors.front();
  stats.max = errors.front();
  for (const double e : errors) {
    sum += e;
    sum_squares += e * e;
    stats.min = std::min(stats.min, e);
    stats.max = std::max(stats.max, e);
  }
  stats.mean = sum / n;
  stats.rmse = std::sqrt(sum_squares / n);
  double sum_deviation_squares = 0.0;  // two passes: no cancellation when errors are alike
  for (const double e : errors) sum_deviation_squares += (e - stats.mean) * (e - stats.mean);
  stats.stddev = std::sqrt(sum_deviation_squares / n);
  stats.median = median_of(std::vector<double>(errors.begin(), errors.end()));
  return stats;
}

Result<AteResult> compute_ate(const Trajectory& ground_truth, const Trajectory& estimate,
                              const AteOptions& options) {
  if (ground_truth.empty()) return Result<AteResult>::failure("ground truth has no poses");
  if (estimate.empty()) return Result<AteResult>::failure("estimate has no poses");
  for (const std::string& error :
       {non_finite_pose(ground_truth, "ground truth"), non_finite_pose(estimate, "estimate")}) {
    if (!error.empty()) return Result<AteResult>::failure(error);
  }
  if (!(options.max_difference_s > 0.0) || !std::isfinite(options.max_difference_s)) {
    return Result<AteResult>::failure("ATE max_difference_s must be a positive number, not " +
                                      std::to_string(options.max_difference_s));
  }

  AteResult result;
  result.matches = associate(ground_truth, estimate, options.max_difference_s);
  const std::size_t n = result.matches.size();
  if (n == 0) {
    return Result<AteResult>::failure(
        "no estimate stamp is within " + seconds_text(options.max_difference_s) +
        " s of a ground-truth stamp (estimate " + stamp_range_text(estimate) + ", ground truth " +
        stamp_range_text(ground_truth) + ")");
  }
  // Fewer points leave the rigid alignment undetermined, and its error an arbitrary zero.
  constexpr std::size_t kMinMatches = 3;
  if (n < kMinMatches) {
    return Result<AteResult>::failure("an ATE needs at least " + std::to_string(kMinMatches) +
                                      " associated poses to align the estimate to the ground truth, found " +
                                      std::to_string(n) + " (estimate " + std::to_string(estimate.size()) +
                                      " poses, ground truth " + std::to_string(ground_truth.size()) + ")");
  }

  Eigen::Matrix3Xd estimate_xyz(3, static_cast<Eigen::Index>(n));
  Eigen::Matrix3Xd truth_xyz(3, static_cast<Eigen::Index>(n));
  for (std::size_t k = 0; k < n; ++k) {
    const auto column = static_cast<Eigen::Index>(k);
    truth_xyz.col(column) = ground_truth[result.matches[k].first_index].T_world_cam.translation();
    estimate_xyz.col(column) = estimate[result.matches[k].second_index].T_world_cam.translation();
  }
  // Umeyama (1991) without scale is Horn's closed form, the one evaluate_ate.py's align() uses:
  // SVD of the cross-covariance, with the reflection guard on det(U) det(V).
  result.T_gtworld_estworld.matrix() = Eigen::umeyama(estimate_xyz, truth_xyz, false);

  result.errors_m.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const auto column = static_cast<Eigen::Index>(k);
    result.errors_m[k] = (result.T_gtworld_estworld * Eigen::Vector3d(estimate_xyz.col(column)) -
                          truth_xyz.col(column))
                             .norm();
  }
  result.translation_m = compute_error_stats(result.errors_m);

  result.aligned_estimate = estimate;
  for (StampedPose& pose : result.aligned_estimate) {
    pose.T_world_cam = result.T_gtworld_estworld * pose.T_world_cam;
  }
  return Result<AteResult>::success(std::move(result));
}

Result<RpeResult> compute_rpe(const Trajectory& ground_truth, const Trajectory& estimate,
                              const RpeOptions& options) {
  if (!(options.delta_s > 0.0) || !std::isfinite(options.delta_s)) {
    return Result<RpeResult>::failure("RPE delta_s must be a positive number, not " +
                                      std::to_string(options.delta_s));
  }
  if (!(options.max_gt_difference_s >= 0.0) || !std::isfinite(options.max_gt_difference_s)) {
    return Result<RpeResult>::failure("RPE max_gt_difference_s must be >= 0, not " +
                                      std::to_string(options.max_gt_difference_s));
  }
  for (const std::string& error :
       {non_finite_pose(ground_truth, "ground truth"), non_finite_pose(estimate, "estimate")}) {
    if (!error.empty()) return Result<RpeResult>::failure(error);
  }
  const SortedTrajectory truth = sort_unique(ground_truth);
  const SortedTrajectory est = sort_unique(estimate);
  if (truth.stamps_s.size() < 2) {
    return Result<RpeResult>::failure("ground truth has fewer than 2 poses");
  }
  if (est.stamps_s.size() < 2) return Result<RpeResult>::failure("estimate has fewer than 2 poses");

  const double max_gt_difference_s = gt_difference_or_default(truth, options.max_gt_difference_s);

  RpeResult result;
  result.delta_s = options.delta_s;
  const std::size_t n = est.stamps_s.size();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t j = closest_index(est.stamps_s, est.stamps_s[i] + options.delta_s);
    if (j == n - 1) continue;  // evaluate_rpe.py's end-of-trajectory rule
    const double stamp_est_0_s = est.stamps_s[i];
    const double stamp_est_1_s = est.stamps_s[j];
    const RelativePoseError error = error_against_truth(
        truth, stamp_est_0_s, stamp_est_1_s, est.poses[i]->inverse() * *est.poses[j], max_gt_difference_s);
    if (!error.has_ground_truth) continue;

    RpePair pair;
    pair.stamp_est_0_s = stamp_est_0_s;
    pair.stamp_est_1_s = stamp_est_1_s;
    pair.stamp_gt_0_s = error.stamp_gt_from_s;
    pair.stamp_gt_1_s = error.stamp_gt_to_s;
    pair.translation_m = error.translation_m;
    pair.rotation_deg = error.rotation_deg;
    result.pairs.push_back(pair);
  }
  if (result.pairs.empty()) {
    return Result<RpeResult>::failure(
        "no pose pairs " + seconds_text(options.delta_s) + " s apart with ground truth within " +
        seconds_text(max_gt_difference_s) + " s of both (estimate " + stamp_range_text(estimate) +
        ", ground truth " + stamp_range_text(ground_truth) + ")");
  }

  std::vector<double> translation_m_per_s(result.pairs.size());
  std::vector<double> rotation_deg_per_s(result.pairs.size());
  for (std::size_t k = 0; k < result.pairs.size(); ++k) {
    translation_m_per_s[k] = result.pairs[k].translation_m / options.delta_s;
    rotation_deg_per_s[k] = result.pairs[k].rotation_deg / options.delta_s;
  }
  result.translation_m_per_s = compute_error_stats(translation_m_per_s);
  result.rotation_deg_per_s = compute_error_stats(rotation_deg_per_s);
  return Result<RpeResult>::success(std::move(result));
}

Result<std::vector<RelativePoseError>> compute_relative_pose_errors(const Trajectory& ground_truth,
                                                                   std::span<const StampedRelativePose> measured,
                                                                   double max_gt_difference_s) {
  using Errors = std::vector<RelativePoseError>;
  if (!(max_gt_difference_s >= 0.0) || !std::isfinite(max_gt_difference_s)) {
    return Result<Errors>::failure("max_gt_difference_s must be >= 0, not " + std::to_string(max_gt_difference_s));
  }
  if (const std::string error = non_finite_pose(ground_truth, "ground truth"); !error.empty()) {
    return Result<Errors>::failure(error);
  }
  const SortedTrajectory truth = sort_unique(ground_truth);
  if (truth.stamps_s.size() < 2) return Result<Errors>::failure("ground truth has fewer than 2 poses");
  const double max_gap_s = gt_difference_or_default(truth, max_gt_difference_s);
  Errors errors(measured.size());
  for (std::size_t k = 0; k < measured.size(); ++k) {
    const StampedRelativePose& m = measured[k];
    if (!std::isfinite(m.stamp_from_s) || !std::isfinite(m.stamp_to_s) || !m.T_from_to.matrix().allFinite()) continue;
    errors[k] = error_against_truth(truth, m.stamp_from_s, m.stamp_to_s, m.T_from_to, max_gap_s);
  }
  return Result<Errors>::success(std::move(errors));
}

}  // namespace rankslam::eval
