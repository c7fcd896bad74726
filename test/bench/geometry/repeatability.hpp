#pragma once

// Relative repeatability of 3D keypoints (thesis §4.5.1 after Salti et al.; docs/methods.md §12) for
// the geometric front-end's detectors (IS3D, ROS, uniform sampling) and PCL's ISS keypoints as
// an oracle (when PCL is available), on frame pairs with known relative motion.
//
// For a source/target pair with T_target_source: a source keypoint, moved by T_target_source,
// overlaps when a point of the target's sampled cloud lies within 1× the source resolution, and
// is repeatable when, in addition, its nearest target keypoint lies within 2× the source
// resolution; relative repeatability = |repeatable| / |overlapping|. The resolution is the mean
// nearest-neighbour distance of the source's sampled cloud (the cloud the keypoints are taken
// from; the dense cloud's would put the 2× tolerance below the voxel quantisation).
//
// Pairs:
//  - simulated (rankslam::sim): "misaligned by 0°" = the same frame of two recordings with
//    different seeds (same scene and motion, independent sensor noise); 5°, 15°, 20° = frame
//    pairs of one recording whose ground-truth relative rotation lies within ±1° of the angle,
//    those with the least translation first (the camera moves between them, as it would).
//  - real (TUM fr1): frame pairs with the motion-capture ground truth, binned by rotation.

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "rankslam/geometry/config.hpp"
#include "rankslam/geometry/frontend.hpp"

namespace rankslam::geometry::bench {

enum RepeatabilityMethod : int { kMethodIs3d = 0, kMethodRos, kMethodUniform, kMethodIss, kMethodCount };

[[nodiscard]] const char* method_name(int method);

/// True when the build has PCL, so ISS keypoints are computed.
[[nodiscard]] bool have_iss();

/// The sampled cloud of one frame and every detector's keypoints on it (camera frame).
struct FrameKeypoints {
  std::vector<Eigen::Vector3f> cloud;
  float resolution_m = 0.0F;  ///< mean nearest-neighbour distance of `cloud`
  std::array<std::vector<Eigen::Vector3f>, kMethodCount> keypoints;
};

/// One row of the result table: the mean over `pairs` frame pairs of a set.
struct RepeatabilityRow {
  std::string set;                 ///< e.g. "sim office", "fr1_desk_9"
  double misalignment_deg = 0.0;   ///< nominal (simulated) or mean (real) relative rotation
  int pairs = 0;
  std::array<double, kMethodCount> repeatability{};  ///< mean relative repeatability, −1 = n/a
  std::array<double, kMethodCount> keypoints{};      ///< mean keypoints per frame
  /// Each pair's relative repeatability per method (−1 = n/a), for paired comparisons.
  std::vector<std::array<double, kMethodCount>> per_pair;
};

/// How far `method` leads `other` on a row's pairs: mean and standard error of the mean of the
/// per-pair differences (percentage points), over the pairs where both were measured. The pairs
/// share their scene and noise, so the paired spread is the noise an ordering has to clear.
struct PairedLead {
  double mean_points = 0.0;
  double standard_error_points = 0.0;
  int pairs = 0;
};
[[nodiscard]] PairedLead paired_lead(const RepeatabilityRow& row, int method, int other);

struct RepeatabilityOptions {
  GeometryConfig config;
  /// Simulated scenes (rankslam::sim names); each costs two recordings.
  std::vector<std::string> sim_scenes = {"office", "zigzag-plain"};
  int sim_frames = 300;
  /// Pairs per simulated misalignment.
  int pairs_per_angle = 6;
  /// Real TUM recordings (folder names under RANKSLAM_SHARED_DATA/tum), skipped when absent.
  std::vector<std::string> real_recordings = {"fr1_desk_9", "fr1_rpy_head"};
};

/// Keypoints of every method on one depth image (`features` from frontend.make_features()).
[[nodiscard]] std::string extract_frame_keypoints(const cv::Mat& depth, GeometricFrontend& frontend,
                                                  GeometricFeatures& features, FrameKeypoints& out);

/// Relative repeatability of `method` from source to target; −1 when nothing overlaps.
[[nodiscard]] double relative_repeatability(const FrameKeypoints& source,
                                            const FrameKeypoints& target,
                                            const Eigen::Isometry3d& T_target_source, int method,
                                            int* overlapping = nullptr);

/// Every row: simulated scenes at 0, 5, 15, 20° and the real recordings' pairs. Error or empty.
[[nodiscard]] std::string run_repeatability(const RepeatabilityOptions& options,
                                            std::vector<RepeatabilityRow>& rows);

/// The rows as an aligned text table, then the paired leads IS3D − ROS, ROS − uniform and
/// IS3D − ISS per row.
[[nodiscard]] std::string format_repeatability_table(const std::vector<RepeatabilityRow>& rows);

}  // namespace rankslam::geometry::bench
