#pragma once

#include "rankslam/eval/json_writer.hpp"
#include "rankslam/eval/metrics.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/nav/pose_uncertainty.hpp"
#include "rankslam/nav/wheel_prior.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rankslam::eval {

/// Frames by the status a consumer of the pose sees: TRACKING (registered), DEGRADED (the wheels
/// carry the pose), LOST (neither: extrapolated or held).
struct StatusCounts {
  int tracking = 0;
  int degraded = 0;
  int lost = 0;
  int disagreements = 0;   ///< registrations that disagreed with the wheels
  int wheels_trusted = 0;  ///< of which the wheels overruled the registration
  void add(const slam::FrameResult& result);
};

/// report.json's layout version: raised when a key changes meaning or goes, not when one is added.
inline constexpr int kReportFormatVersion = 1;

/// The first report.json entries of every command: `format_version`, `software`
/// ("rankslam <version>") and `command`.
void write_report_header(JsonWriter& json, std::string_view software_version, std::string_view command);

/// The report.json entries `replay` and `run` share: `status_counts`, and how the wheels fared
/// (`wheels` null when they were not used, for `wheels_off_reason`).
void write_status_and_wheels(JsonWriter& json, const StatusCounts& counts, const nav::WheelPrior* wheels,
                             int slip_events, const std::string& wheels_off_reason);

struct Percentiles {
  double median = 0.0;
  double p90 = 0.0;
  double max = 0.0;
};

/// Median, 90th percentile and maximum (nearest rank); zeros for no values.
[[nodiscard]] Percentiles percentiles(std::vector<double> values);

/// `key: {"median", "p90", "max"}`.
void write_percentiles(JsonWriter& json, std::string_view key, const Percentiles& p);

/// One line of frames.csv.
struct FrameRecord {
  double stamp_s = 0.0;
  slam::FrameStatus status = slam::FrameStatus::kFirstFrame;
  int inliers = 0;
  int photometric_matches = 0;
  int photometric_inliers = 0;
  int geometric_matches = 0;
  int geometric_inliers = 0;
  double photometric_weight = 0.0;
  nav::WheelCheck wheels;
  /// The base in the odom frame and the standard deviations PoseQuality sends with it (none:
  /// unknown), and its error against the ground truth (the ground truth's base relative to its
  /// first frame), where there is one: horizontal distance and yaw difference.
  Eigen::Isometry3d T_odom_base = Eigen::Isometry3d::Identity();
  std::optional<nav::PoseSigmas> sigmas;
  std::optional<double> gt_position_error_m;
  std::optional<double> gt_yaw_error_deg;
};

/// How well the sent sigmas cover the odom pose's true error: the frames with a sigma and a
/// ground-truth error, the fraction of them whose error is within 3σ (horizontal distance within
/// 3 position sigmas, yaw within 3 yaw sigmas), and the medians of sigma and error.
struct SigmaCoverage {
  int frames = 0;
  double position_coverage = 0.0;
  double yaw_coverage = 0.0;
  double median_position_sigma_m = 0.0;
  double median_position_error_m = 0.0;
  double median_yaw_sigma_deg = 0.0;
  double median_yaw_error_deg = 0.0;
};
[[nodiscard]] SigmaCoverage sigma_coverage(const std::vector<FrameRecord>& records);

/// Fills each record's gt_*_error from `ground_truth` (camera poses, associated by stamp, the
/// TUM benchmark's way) with the camera mounted at T_base_cam.
void add_odom_errors(std::vector<FrameRecord>& records, const Trajectory& ground_truth,
                     const Eigen::Isometry3d& T_base_cam);

/// The frames.csv line of a processed frame.
[[nodiscard]] FrameRecord frame_record(double stamp_s, const slam::FrameResult& result);

/// Per-frame status and how vision compared with the wheels, for plots and checks: CSV
/// (RFC 4180: comma-separated, one header line naming the columns).
[[nodiscard]] std::string frames_csv(const std::vector<FrameRecord>& records);

/// Whether a loop closure's measured relative pose is farther from the ground truth's than a
/// correct closure ever is: it joined two places that are not where the graph now puts them.
[[nodiscard]] bool is_false_closure(const RelativePoseError& error);

/// A frame found in the map after tracking was lost (or in a loaded map): its index among the
/// processed frames, its stamp, the pose the relocalisation gave and the frames it withdrew.
struct RelocalisationRecord {
  std::uint64_t frame = 0;
  double stamp_s = 0.0;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  int retracted_frames = 0;
};

/// A relocalised position against the ground truth, through the ATE's alignment of the whole
/// run (a rotation error is not given: the ATE aligns positions only, which leave the rotation
/// loose on a camera that mostly turns).
struct RelocalisationError {
  /// False when no ground-truth pose lies within max_difference_s of the stamp.
  bool has_ground_truth = false;
  double translation_m = 0.0;
};

/// Each relocalisation's error: T_gtworld_estworld·t_world_cam against the nearest ground-truth
/// position.
[[nodiscard]] std::vector<RelocalisationError> relocalisation_errors(const Trajectory& ground_truth,
                                                                     const AteResult& ate,
                                                                     const std::vector<RelocalisationRecord>& records,
                                                                     double max_difference_s);

/// A relocalisation farther from the ground truth than a correct loop closure ever is (the
/// translation threshold of is_false_closure): it put the camera in another place.
[[nodiscard]] bool is_false_relocalisation(const RelocalisationError& error);

/// Each accepted loop closure, with its error against the ground truth where there is one (empty
/// fields where there is none); CSV as frames_csv.
[[nodiscard]] std::string loop_closures_csv(const std::vector<slam::LoopClosure>& closures,
                                            const std::vector<RelativePoseError>& errors);

}  // namespace rankslam::eval
