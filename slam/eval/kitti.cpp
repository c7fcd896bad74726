#include "rankslam/eval/kitti.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace rankslam::eval {

Result<SegmentErrors> compute_segment_errors(const Trajectory& ground_truth, const Trajectory& estimate,
                                             const SegmentOptions& options) {
  if (options.step_frames < 1) return Result<SegmentErrors>::failure("segment step_frames must be at least 1");
  if (options.lengths_m.empty()) return Result<SegmentErrors>::failure("no segment lengths given");
  for (const double length : options.lengths_m) {
    if (!(length > 0.0 && std::isfinite(length))) return Result<SegmentErrors>::failure("segment lengths must be positive");
  }
  const auto by_stamp = [](const StampedPose& a, const StampedPose& b) { return a.stamp_s < b.stamp_s; };
  Trajectory gt = ground_truth;
  Trajectory est = estimate;
  std::sort(gt.begin(), gt.end(), by_stamp);
  std::sort(est.begin(), est.end(), by_stamp);
  std::vector<StampMatch> matches = associate(gt, est, options.max_difference_s);
  std::sort(matches.begin(), matches.end(),
            [&](const StampMatch& a, const StampMatch& b) { return gt[a.first_index].stamp_s < gt[b.first_index].stamp_s; });
  if (matches.size() < 2) return Result<SegmentErrors>::failure("fewer than 2 poses associate with the ground truth");

  const std::size_t n = matches.size();
  std::vector<double> distance;
  distance.reserve(n);
  double travelled = 0.0;
  Eigen::Vector3d previous = gt[matches.front().first_index].T_world_cam.translation();
  for (const StampMatch& match : matches) {
    const Eigen::Vector3d position = gt[match.first_index].T_world_cam.translation();
    travelled += (position - previous).norm();
    previous = position;
    distance.push_back(travelled);
  }
  SegmentErrors result;
  result.path_length_m = distance.back();
  double sum_t = 0.0;
  double sum_r = 0.0;
  for (const double length : options.lengths_m) {
    SegmentLengthErrors per;
    per.length_m = length;
    for (std::size_t first = 0; first < n; first += static_cast<std::size_t>(options.step_frames)) {
      const auto it = std::upper_bound(distance.begin() + static_cast<std::ptrdiff_t>(first), distance.end(),
                                       distance[first] + length);
      if (it == distance.end()) break;  // later firsts reach no farther
      const auto last = static_cast<std::size_t>(it - distance.begin());
      const Eigen::Isometry3d& q0 = gt[matches[first].first_index].T_world_cam;
      const Eigen::Isometry3d& q1 = gt[matches[last].first_index].T_world_cam;
      const Eigen::Isometry3d& p0 = est[matches[first].second_index].T_world_cam;
      const Eigen::Isometry3d& p1 = est[matches[last].second_index].T_world_cam;
      const Eigen::Isometry3d error = (p0.inverse() * p1).inverse() * (q0.inverse() * q1);
      // The devkit's rotation error: acos of the clamped (trace − 1) / 2.
      const double cos_angle = std::clamp(0.5 * (error.linear().trace() - 1.0), -1.0, 1.0);
      const double t = error.translation().norm() / length;
      const double r = std::acos(cos_angle) / length;
      per.translation_percent += t;
      per.rotation_deg_per_m += r;
      sum_t += t;
      sum_r += r;
      ++per.segments;
    }
    if (per.segments == 0) continue;
    per.translation_percent *= 100.0 / per.segments;
    per.rotation_deg_per_m *= 180.0 / std::numbers::pi / per.segments;
    result.segments += per.segments;
    result.per_length.push_back(per);
  }
  if (result.segments == 0) {
    char text[160];
    std::snprintf(text, sizeof text, "the ground-truth path is %.3f m long, shorter than the shortest segment (%.0f m)",
                  result.path_length_m, *std::min_element(options.lengths_m.begin(), options.lengths_m.end()));
    return Result<SegmentErrors>::failure(text);
  }
  result.translation_percent = 100.0 * sum_t / result.segments;
  result.rotation_deg_per_m = 180.0 / std::numbers::pi * sum_r / result.segments;
  return Result<SegmentErrors>::success(std::move(result));
}

}  // namespace rankslam::eval
