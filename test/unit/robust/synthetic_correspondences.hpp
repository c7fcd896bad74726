#pragma once

// Synthetic 3D–3D correspondences as an RGB-D camera measures them: points 0.5–4 m in front of
// a 640×480 pinhole camera (f = 525 px), Kinect depth noise σ_z = 1.425e-3·z² along the ray plus
// 1 mm lateral on both measured points, a share of uniform outliers (random points in the
// target view frustum) and optionally a second rigid motion (a moving object).

#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rankslam::robust::testing {

enum class PointKind : std::uint8_t { kInlier, kOutlier, kSecondMotion };

struct SceneConfig {
  int points = 500;
  double outlier_fraction = 0.0;        ///< Uniform outliers in the target frustum.
  double second_motion_fraction = 0.0;  ///< Points following a second rigid motion.
  double min_depth_m = 0.5;
  double max_depth_m = 4.0;
  double axial_coefficient_per_m = 1.425e-3;  ///< σ_z = a·z²; 0 disables depth noise.
  double lateral_sigma_m = 1e-3;              ///< per lateral axis; 0 disables.
  double max_rotation_deg = 10.0;             ///< frame-to-frame motion magnitude
  double max_translation_m = 0.2;
  double second_rotation_deg = 20.0;  ///< the moving object's own motion on top of the camera's
  double second_translation_m = 0.3;
  std::uint64_t seed = 1;
};

struct Scene {
  Eigen::Matrix3Xd src;  ///< measured points in frame s
  Eigen::Matrix3Xd dst;  ///< measured points in frame t
  Eigen::Isometry3d T_t_s = Eigen::Isometry3d::Identity();         ///< true (dominant) motion
  Eigen::Isometry3d T_t_s_second = Eigen::Isometry3d::Identity();  ///< the moving object's
  std::vector<PointKind> kind;
};

Scene make_scene(const SceneConfig& config);

/// Translation error [m] and rotation error [rad] of an estimate against the truth.
struct PoseError {
  double translation_m = 0.0;
  double rotation_rad = 0.0;
};
PoseError pose_error(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth);

}  // namespace rankslam::robust::testing
