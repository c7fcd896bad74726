#include "synthetic_correspondences.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

namespace rankslam::robust::testing {
namespace {

constexpr double kFocalPx = 525.0;
constexpr double kCx = 319.5;
constexpr double kCy = 239.5;
constexpr double kWidthPx = 640.0;
constexpr double kHeightPx = 480.0;

Eigen::Vector3d random_frustum_point(std::mt19937_64& rng, double min_depth_m, double max_depth_m) {
  std::uniform_real_distribution<double> u(0.0, kWidthPx);
  std::uniform_real_distribution<double> v(0.0, kHeightPx);
  std::uniform_real_distribution<double> z(min_depth_m, max_depth_m);
  const double depth = z(rng);
  return {(u(rng) - kCx) * depth / kFocalPx, (v(rng) - kCy) * depth / kFocalPx, depth};
}

Eigen::Vector3d random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Vector3d v(g(rng), g(rng), g(rng));
  return v.normalized();
}

Eigen::Isometry3d random_motion(std::mt19937_64& rng, double max_rotation_deg,
                                double max_translation_m) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const double angle = unit(rng) * max_rotation_deg * std::numbers::pi / 180.0;
  T.linear() = Eigen::AngleAxisd(angle, random_unit(rng)).toRotationMatrix();
  T.translation() = random_unit(rng) * unit(rng) * max_translation_m;
  return T;
}

/// Kinect-like measurement of a point in its camera frame: axial noise along the viewing ray,
/// lateral noise across it.
Eigen::Vector3d measure(std::mt19937_64& rng, const Eigen::Vector3d& p, const SceneConfig& c) {
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Vector3d ray = p.normalized();
  const Eigen::Vector3d e1 = ray.unitOrthogonal();
  const Eigen::Vector3d e2 = ray.cross(e1);
  const double sigma_axial = c.axial_coefficient_per_m * p.z() * p.z();
  return p + ray * (sigma_axial * g(rng)) + e1 * (c.lateral_sigma_m * g(rng)) +
         e2 * (c.lateral_sigma_m * g(rng));
}

}  // namespace

Scene make_scene(const SceneConfig& config) {
  std::mt19937_64 rng(config.seed);
  Scene scene;
  const int n = config.points;
  scene.src.resize(3, n);
  scene.dst.resize(3, n);
  scene.kind.assign(static_cast<std::size_t>(n), PointKind::kInlier);
  scene.T_t_s = random_motion(rng, config.max_rotation_deg, config.max_translation_m);
  scene.T_t_s_second =
      random_motion(rng, config.second_rotation_deg, 0.0) * scene.T_t_s;
  scene.T_t_s_second.translation() += random_unit(rng) * config.second_translation_m;

  const auto outliers = static_cast<int>(std::lround(config.outlier_fraction * n));
  const auto second = static_cast<int>(std::lround(config.second_motion_fraction * n));
  std::vector<int> shuffled(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) shuffled[static_cast<std::size_t>(i)] = i;
  std::shuffle(shuffled.begin(), shuffled.end(), rng);
  for (int k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(shuffled[static_cast<std::size_t>(k)]);
    if (k < outliers) {
      scene.kind[i] = PointKind::kOutlier;
    } else if (k < outliers + second) {
      scene.kind[i] = PointKind::kSecondMotion;
    }
  }

  for (int i = 0; i < n; ++i) {
    const PointKind kind = scene.kind[static_cast<std::size_t>(i)];
    const Eigen::Isometry3d& motion =
        kind == PointKind::kSecondMotion ? scene.T_t_s_second : scene.T_t_s;
    Eigen::Vector3d p_s;
    Eigen::Vector3d p_t;
    do {  // keep both views in front of their cameras
      p_s = random_frustum_point(rng, config.min_depth_m, config.max_depth_m);
      p_t = motion * p_s;
    } while (p_t.z() < 0.3);
    if (kind == PointKind::kOutlier) {
      p_t = random_frustum_point(rng, config.min_depth_m, config.max_depth_m);
    }
    scene.src.col(i) = measure(rng, p_s, config);
    scene.dst.col(i) = measure(rng, p_t, config);
  }
  return scene;
}

PoseError pose_error(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  const Eigen::Matrix3d delta = truth.linear().transpose() * estimate.linear();
  const Eigen::Vector3d skew(delta(2, 1) - delta(1, 2), delta(0, 2) - delta(2, 0),
                             delta(1, 0) - delta(0, 1));
  return {(estimate.translation() - truth.translation()).norm(),
          std::atan2(0.5 * skew.norm(), 0.5 * (delta.trace() - 1.0))};
}

}  // namespace rankslam::robust::testing
