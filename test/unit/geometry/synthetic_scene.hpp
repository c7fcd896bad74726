#pragma once

// Analytic depth images for the geometric front-end's tests: rectangles and spheres ray-cast by
// a distortion-free pinhole camera, with optional Gaussian depth noise.

#include <cstdint>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "rankslam/hal/calibration.hpp"

namespace rankslam::geometry::testing {

struct Rectangle {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitX();  ///< unit
  Eigen::Vector3d axis_v = Eigen::Vector3d::UnitY();  ///< unit, ⟂ axis_u
  double half_u = 1.0;
  double half_v = 1.0;
};

struct Sphere {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.1;
};

struct Scene {
  std::vector<Rectangle> rectangles;
  std::vector<Sphere> spheres;
};

/// 640 × 480 pinhole camera (fx = fy = 525, centred), no distortion.
[[nodiscard]] hal::CameraCalibration test_calibration();

/// Depth image (CV_16UC1, 5000 units per metre, 0 = no hit) of `scene` seen from T_world_cam
/// (optical frame: x right, y down, z forward). noise_sigma_per_m2: σ = this · z² of added
/// Gaussian noise (0: exact), from a generator seeded with `seed`.
[[nodiscard]] cv::Mat render_depth(const Scene& scene, const hal::CameraCalibration& calibration,
                                   const Eigen::Isometry3d& T_world_cam,
                                   double noise_sigma_per_m2 = 0.0, std::uint32_t seed = 1);

/// A room corner: floor (z = 0), walls x = 0 and y = 0, a 0.5 m box standing at (1, 1) and a
/// 0.2 m sphere on the floor at (0.6, 1.6). Walls and floor extend 4 m.
[[nodiscard]] Scene room_corner();

/// Camera 2.2 m from the room corner's box, looking at it from above: optical axis toward
/// `target` from `eye` (world), image x to the right, no roll.
[[nodiscard]] Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target);

}  // namespace rankslam::geometry::testing
