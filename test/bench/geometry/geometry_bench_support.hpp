#pragma once

// Shared by the geometric front-end's bench tests, tools and benchmarks: recordings played
// through hal_replay's ReplayDepthCamera, depth-only frame-to-frame odometry with
// GeometricFrontend, simulated recordings, and ground-truth lookups.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "rankslam/eval/trajectory.hpp"
#include "rankslam/geometry/config.hpp"
#include "rankslam/hal/calibration.hpp"

namespace rankslam::geometry::bench {

/// Real recordings beside the checkout (RANKSLAM_SHARED_DATA); empty when the data is absent.
[[nodiscard]] std::filesystem::path shared_recording(const std::string& name);

/// A recording's depth images in memory, with their stamps and the ground-truth pose of each
/// (nullopt where no ground-truth stamp lies within 0.02 s).
///
/// Stamps are the depth images' own: TUM's colour and depth streams are not synchronised (up to
/// ~15 ms apart), and at fr1_rpy's 90°/s the colour stamp's ground truth is off by up to ~1°
/// for a depth-only estimate.
struct DepthSequence {
  hal::Calibration calibration;
  std::vector<double> stamps_s;
  std::vector<cv::Mat> depth;  ///< CV_16UC1, owned copies
  std::vector<std::optional<Eigen::Isometry3d>> T_world_cam;
};

/// Reads every depth image of a recording through ReplayDepthCamera (at most max_frames, 0 = all).
/// Error message or empty.
[[nodiscard]] std::string load_depth_sequence(const std::filesystem::path& root,
                                              DepthSequence& sequence, int max_frames = 0);

/// Writes a simulated recording of `scene` (rankslam::sim) into a fresh directory under the
/// system temp folder, reusing it when an earlier call in this process wrote the same scene,
/// length and seed; the directories are removed when the process exits. Error message or empty.
[[nodiscard]] std::string simulated_recording(const std::string& scene, int frames,
                                              std::uint64_t seed, std::filesystem::path& root);

/// Depth-only frame-to-frame odometry over a recording.
struct OdometryResult {
  eval::Trajectory estimate;
  int frames = 0;
  int failed_extractions = 0;
  int failed_registrations = 0;
  double mean_matches = 0.0;
  double mean_inliers = 0.0;
  double mean_keypoints = 0.0;
  double mean_sampled_points = 0.0;
  std::vector<double> frame_ms;  ///< wall time of extract + register per frame
  /// One line per frame: status, cloud and keypoint counts, matches, inliers.
  std::vector<std::string> frame_log;
  /// TUM ATE RMSE against the recording's ground truth (negative when it has none).
  double ate_rmse_m = -1.0;
  double rpe_translation_m_per_s = -1.0;
  double rpe_rotation_deg_per_s = -1.0;
};

/// Plays `root` through ReplayDepthCamera, extracts features from every depth image, registers
/// each frame to the previous one and concatenates G_n = G_{n−1}·T_prev_cur (a failed
/// registration keeps the previous pose). Poses carry the depth images' stamps (see
/// DepthSequence). Evaluates against groundtruth.txt when present.
/// Error message or empty.
[[nodiscard]] std::string run_geometric_odometry(const std::filesystem::path& root,
                                                 const GeometryConfig& config,
                                                 OdometryResult& result, int max_frames = 0);


}  // namespace rankslam::geometry::bench
