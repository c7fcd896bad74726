#pragma once

// Stereo dataset readers: the EuRoC MAV ASL layout and the KITTI odometry layout. Set-up code:
// reads every index and calibration file once, allocates freely, and reports bad input as a
// message naming the file and the field or line.

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/types.hpp>

#include "rankslam/eval/result.hpp"
#include "rankslam/eval/trajectory.hpp"

namespace rankslam::stereo {

/// One pinhole camera with radial-tangential distortion (EuRoC's `radtan`; zero for KITTI).
struct CameraIntrinsics {
  cv::Size size;                          ///< image size in pixels
  double fu = 0.0, fv = 0.0;              ///< focal lengths [px]
  double cu = 0.0, cv = 0.0;              ///< principal point [px]
  std::array<double, 4> radtan{};         ///< k1, k2, p1, p2
};

struct StereoCalibration {
  CameraIntrinsics left;
  CameraIntrinsics right;
  /// Maps points of the left camera's optical frame into the right camera's.
  Eigen::Isometry3d T_right_left = Eigen::Isometry3d::Identity();
  /// True when the images are already rectified (KITTI): the rectifier passes them through.
  bool rectified = false;
};

struct StereoFrameFiles {
  std::int64_t stamp_ns = 0;
  double stamp_s = 0.0;
  std::filesystem::path left;
  std::filesystem::path right;
};

enum class DatasetLayout { euroc, kitti };

struct StereoDataset {
  DatasetLayout layout = DatasetLayout::euroc;
  StereoCalibration calibration;
  std::vector<StereoFrameFiles> frames;  ///< in time order
  /// The left camera's optical frame in the ground-truth world, when the dataset has one.
  std::optional<eval::Trajectory> ground_truth;
  std::filesystem::path ground_truth_file;  ///< where it came from (empty: none)
  /// Left-camera frames of cam0 without a right image of the same stamp (EuRoC), skipped.
  int unpaired_frames = 0;
};

/// EuRoC ASL layout: DIR/mav0/cam{0,1}/{data.csv,data/,sensor.yaml}; pairs by identical stamp.
/// Ground truth: `ground_truth` when not empty (TUM format), else DIR/groundtruth.txt (TUM, the
/// left camera's optical frame), else DIR/groundtruth_cam0_euroc.txt (ns, qw first), else none.
[[nodiscard]] eval::Result<StereoDataset> read_euroc(const std::filesystem::path& dir,
                                                     const std::filesystem::path& ground_truth = {});

/// KITTI odometry layout: DIR/image_0/NNNNNN.png, DIR/image_1/, DIR/calib.txt (P0, P1), DIR/times.txt;
/// ground truth `ground_truth` when not empty, else DIR/poses.txt when present (3×4 rows of
/// T_world_cam0 per frame; a file ending in .txt whose lines hold 8 numbers is read as TUM).
[[nodiscard]] eval::Result<StereoDataset> read_kitti(const std::filesystem::path& dir,
                                                     const std::filesystem::path& ground_truth = {});

/// read_euroc when DIR/mav0 exists, read_kitti when DIR/calib.txt exists, else a failure.
[[nodiscard]] eval::Result<StereoDataset> read_stereo_dataset(const std::filesystem::path& dir,
                                                              const std::filesystem::path& ground_truth = {});

/// KITTI poses.txt text: one 3×4 row-major T_world_cam0 per line, stamped by `stamps_s` (equal
/// count). Errors read "<source_name>:<line>: <what>".
[[nodiscard]] eval::Result<eval::Trajectory> parse_kitti_poses(const std::string& text,
                                                               const std::vector<double>& stamps_s,
                                                               const std::string& source_name);

}  // namespace rankslam::stereo
