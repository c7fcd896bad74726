#pragma once

// A whole stereo sequence through the odometry, its accuracy against the dataset's ground truth,
// and the report `rankslam stereo-vo` writes. Offline tooling: allocates freely.

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "rankslam/eval/kitti.hpp"
#include "rankslam/eval/metrics.hpp"
#include "rankslam/stereo/dataset.hpp"
#include "rankslam/stereo/odometry.hpp"

namespace rankslam::stereo {

struct SequenceOptions {
  int max_frames = 0;  ///< process at most this many stereo pairs (0 = all)
};

struct StereoRun {
  /// The (raw, unrectified) left camera's optical frame in the world of the first frame's, one
  /// pose per processed pair, stamped as the images.
  eval::Trajectory trajectory;
  std::vector<StereoFrameResult> frames;
  int unreadable_pairs = 0;                ///< pairs whose images could not be read (skipped)
  std::vector<std::string> warnings;       ///< one per unreadable pair
  RectifiedRig rig;
};

/// Set-up (rectifier, odometry), then every pair: read as grey, rectify, track. Fails with a
/// message when the configuration is out of range, the calibration cannot be rectified or no
/// pair could be read. `progress` (optional) is called after each pair.
[[nodiscard]] eval::Result<StereoRun> run_stereo_sequence(
    const StereoDataset& dataset, const StereoOdometryConfig& config, const SequenceOptions& options = {},
    const std::function<void(int, const StereoFrameResult&)>& progress = {});

struct StereoAccuracy {
  std::optional<eval::EvalResult> eval;     ///< ATE and RPE
  std::string eval_missing_reason;
  std::optional<eval::SegmentErrors> segments;  ///< KITTI segment errors
  std::string segments_missing_reason;
  /// ATE RMSE of a trajectory that never moves (every pose the first), against the same ground
  /// truth: the figure a nearly static sequence must beat.
  std::optional<double> zero_motion_ate_rmse_m;
};

[[nodiscard]] StereoAccuracy evaluate_stereo_run(const StereoRun& run, const std::optional<eval::Trajectory>& ground_truth);

/// report.json: dataset, configuration (features, BA on/off), frames, features, per-frame ms,
/// ATE, RPE, the zero-motion baseline and the KITTI segment errors (null with a reason when absent).
[[nodiscard]] std::string stereo_report_json(const StereoDataset& dataset, const std::filesystem::path& dataset_dir,
                                             const StereoOdometryConfig& config, const StereoRun& run,
                                             const StereoAccuracy& accuracy);

/// The figures as "key value" lines for the terminal.
[[nodiscard]] std::string format_stereo_summary(const StereoRun& run, const StereoAccuracy& accuracy);

}  // namespace rankslam::stereo
