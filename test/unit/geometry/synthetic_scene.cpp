#include "synthetic_scene.hpp"

#include <cmath>
#include <limits>
#include <random>

namespace rankslam::geometry::testing {

hal::CameraCalibration test_calibration() {
  hal::CameraCalibration calibration;
  calibration.width = 640;
  calibration.height = 480;
  calibration.fx = 525.0;
  calibration.fy = 525.0;
  calibration.cx = 319.5;
  calibration.cy = 239.5;
  return calibration;
}

cv::Mat render_depth(const Scene& scene, const hal::CameraCalibration& calibration,
                     const Eigen::Isometry3d& T_world_cam, double noise_sigma_per_m2,
                     std::uint32_t seed) {
  cv::Mat depth(calibration.height, calibration.width, CV_16UC1, cv::Scalar(0));
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const Eigen::Vector3d origin = T_world_cam.translation();
  for (int v = 0; v < calibration.height; ++v) {
    for (int u = 0; u < calibration.width; ++u) {
      // Ray with unit z in the camera frame: the hit's parameter is its depth.
      const Eigen::Vector3d ray_cam((u - calibration.cx) / calibration.fx,
                                    (v - calibration.cy) / calibration.fy, 1.0);
      const Eigen::Vector3d ray = T_world_cam.linear() * ray_cam;
      double best = std::numeric_limits<double>::infinity();
      for (const Rectangle& r : scene.rectangles) {
        const Eigen::Vector3d n = r.axis_u.cross(r.axis_v);
        const double denom = n.dot(ray);
        if (std::abs(denom) < 1e-12) continue;
        const double t = n.dot(r.center - origin) / denom;
        if (!(t > 0.0) || t >= best) continue;
        const Eigen::Vector3d local = origin + t * ray - r.center;
        if (std::abs(local.dot(r.axis_u)) <= r.half_u && std::abs(local.dot(r.axis_v)) <= r.half_v) {
          best = t;
        }
      }
      for (const Sphere& s : scene.spheres) {
        const Eigen::Vector3d oc = origin - s.center;
        const double a = ray.squaredNorm();
        const double b = 2.0 * oc.dot(ray);
        const double c = oc.squaredNorm() - s.radius * s.radius;
        const double disc = b * b - 4.0 * a * c;
        if (disc < 0.0) continue;
        const double t = (-b - std::sqrt(disc)) / (2.0 * a);
        if (t > 0.0 && t < best) best = t;
      }
      if (!std::isfinite(best)) continue;
      double z = best;
      if (noise_sigma_per_m2 > 0.0) z += noise_sigma_per_m2 * z * z * gauss(rng);
      const double raw = std::round(z * 5000.0);
      if (raw > 0.0 && raw < 65535.0) depth.at<std::uint16_t>(v, u) = static_cast<std::uint16_t>(raw);
    }
  }
  return depth;
}

Scene room_corner() {
  Scene scene;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY();
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  scene.rectangles.push_back({Eigen::Vector3d(2.0, 2.0, 0.0), x, y, 2.0, 2.0});    // floor
  scene.rectangles.push_back({Eigen::Vector3d(0.0, 2.0, 1.25), y, z, 2.0, 1.25});  // wall x = 0
  scene.rectangles.push_back({Eigen::Vector3d(2.0, 0.0, 1.25), x, z, 2.0, 1.25});  // wall y = 0
  // Box 0.5 m on a side at (1, 1): top and four faces.
  const Eigen::Vector3d c(1.0, 1.0, 0.25);
  scene.rectangles.push_back({c + 0.25 * z, x, y, 0.25, 0.25});
  scene.rectangles.push_back({c + 0.25 * x, y, z, 0.25, 0.25});
  scene.rectangles.push_back({c - 0.25 * x, y, z, 0.25, 0.25});
  scene.rectangles.push_back({c + 0.25 * y, x, z, 0.25, 0.25});
  scene.rectangles.push_back({c - 0.25 * y, x, z, 0.25, 0.25});
  scene.spheres.push_back({Eigen::Vector3d(0.6, 1.6, 0.2), 0.2});
  return scene;
}

Eigen::Isometry3d look_at(const Eigen::Vector3d& eye, const Eigen::Vector3d& target) {
  const Eigen::Vector3d forward = (target - eye).normalized();
  Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ());
  if (right.norm() < 1e-9) right = Eigen::Vector3d::UnitX();
  right.normalize();
  const Eigen::Vector3d down = forward.cross(right);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = right;
  T.linear().col(1) = down;
  T.linear().col(2) = forward;
  T.translation() = eye;
  return T;
}

}  // namespace rankslam::geometry::testing
