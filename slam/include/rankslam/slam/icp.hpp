#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/slam/config.hpp"

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <memory>
#include <string_view>
#include <vector>

namespace rankslam::slam {

/// A depth image reduced for ICP: invalid depth removed, depth limited, one centroid (and, for
/// point-to-plane, one averaged normal) per occupied voxel. Capacity is fixed at set-up.
struct VoxelCloud {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;  ///< Unit, towards the camera; empty unless requested.

  [[nodiscard]] std::size_t size() const { return points.size(); }
};

struct IcpSettings {
  IcpMode mode = IcpMode::kOff;
  double max_depth_m = 4.0;             ///< Farther depth is dropped (thesis: 4 m).
  double voxel_m = 0.02;                ///< Voxel edge of the cloud filter (thesis: 2 cm).
  int pixel_stride = 2;                 ///< Every stride-th pixel in u and v feeds the voxel grid.
  double max_correspondence_m = 0.05;   ///< Closest points farther apart are not paired.
  int max_iterations = 20;
  double min_update = 1e-5;             ///< Stop when rotation (rad) and translation (m) steps fall below.
  int max_source_points = 4000;         ///< Source points used per iteration (evenly thinned).
};

struct IcpResult {
  bool ok = false;
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  int iterations = 0;
  int correspondences = 0;
  double rmse_m = 0.0;
  std::string_view failure_reason;
};

/// Builds voxel clouds from depth images and aligns a source cloud to a target cloud by ICP with
/// a k-d tree (nanoflann) over the target. Buffers are allocated at construction; building the
/// target's k-d tree allocates its nodes (nanoflann's pool), which happens only when the target
/// changes.
class IcpRefiner {
 public:
  IcpRefiner(const IcpSettings& settings, const camera::DepthCameraModel& camera);
  ~IcpRefiner();
  IcpRefiner(const IcpRefiner&) = delete;
  IcpRefiner& operator=(const IcpRefiner&) = delete;

  [[nodiscard]] const IcpSettings& settings() const { return settings_; }
  /// Largest number of points a cloud of this camera can hold.
  [[nodiscard]] std::size_t cloud_capacity() const;

  /// Filters `depth` (raw units, CV_16UC1) into `cloud` (whose vectors must be reserved to
  /// cloud_capacity()).
  void build_cloud(const cv::Mat& depth, VoxelCloud& cloud);

  /// Makes `target` the cloud later calls align to; `target` must outlive that use. `key`
  /// identifies it: the same key again skips rebuilding the k-d tree.
  void set_target(const VoxelCloud& target, std::int64_t key);

  /// Aligns `source` to the target starting from `T_target_source_initial`.
  [[nodiscard]] IcpResult align(const VoxelCloud& source, const Eigen::Isometry3d& T_target_source_initial);

 private:
  struct Impl;
  IcpSettings settings_;
  const camera::DepthCameraModel& camera_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rankslam::slam
