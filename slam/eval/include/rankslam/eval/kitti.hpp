#pragma once

#include <vector>

#include "rankslam/eval/associate.hpp"
#include "rankslam/eval/result.hpp"
#include "rankslam/eval/trajectory.hpp"

namespace rankslam::eval {

struct SegmentOptions {
  /// Segment lengths along the ground-truth path [m] (the KITTI devkit's 100, 200, …, 800).
  std::vector<double> lengths_m = {100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0};
  /// First frames of segments are every step_frames-th associated pose (the devkit's 10).
  int step_frames = 10;
  /// Association window between estimate and ground-truth stamps.
  double max_difference_s = kDefaultMaxDifference_s;
};

struct SegmentLengthErrors {
  double length_m = 0.0;
  int segments = 0;
  double translation_percent = 0.0;  ///< mean |t(E)| / length × 100
  double rotation_deg_per_m = 0.0;   ///< mean angle(E) / length, degrees per metre
};

struct SegmentErrors {
  int segments = 0;                  ///< over all lengths
  double translation_percent = 0.0;  ///< mean over every segment of every length, as the devkit
  double rotation_deg_per_m = 0.0;
  double path_length_m = 0.0;        ///< ground-truth path length over the associated poses
  std::vector<SegmentLengthErrors> per_length;  ///< lengths with at least one segment
};

/// KITTI odometry segment errors (Geiger et al., CVPR 2012; devkit's calcSequenceErrors): the
/// poses are associated by stamp; for every step_frames-th pose `first` and every length L, `last`
/// is the first pose whose ground-truth path distance from `first` exceeds L; then
/// E = (P_first⁻¹·P_last)⁻¹·(Q_first⁻¹·Q_last) (P estimate, Q ground truth) gives |t(E)|/L and
/// angle(E)/L. Fails, saying why, when no segment fits (a path shorter than the shortest length).
[[nodiscard]] Result<SegmentErrors> compute_segment_errors(const Trajectory& ground_truth,
                                                           const Trajectory& estimate,
                                                           const SegmentOptions& options = {});

}  // namespace rankslam::eval
