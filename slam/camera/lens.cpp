#include "rankslam/camera/lens.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace rankslam::camera {

namespace {

constexpr double kScanStepRad = 1e-3;

}  // namespace

Lens::Lens(const hal::CameraCalibration& calibration, double max_field_angle_rad)
    : calibration_(calibration), fisheye_(calibration.model == hal::CameraModel::kFisheye) {
  if (max_field_angle_rad > 0.0) {
    max_field_angle_rad_ = max_field_angle_rad;
    return;
  }
  // Walk out from the axis until the distorted radius stops growing.
  const double limit = fisheye_ ? std::numbers::pi : std::numbers::pi / 2.0 - kScanStepRad;
  double previous = 0.0;
  double theta = kScanStepRad;
  for (; theta <= limit; theta += kScanStepRad) {
    const double radius = fisheye_ ? fisheye_distort(theta) : pinhole_distort({std::tan(theta), 0.0}).x();
    if (!(radius > previous)) break;
    previous = radius;
  }
  max_field_angle_rad_ = std::min(theta - kScanStepRad, limit);
  if (calibration.field_of_view_deg > 0.0) {
    max_field_angle_rad_ = std::min(max_field_angle_rad_, calibration.field_of_view_deg * std::numbers::pi / 360.0);
  }
}

double Lens::fisheye_distort(double theta) const {
  const auto& k = calibration_.distortion;
  const double t2 = theta * theta;
  return theta * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
}

double Lens::pinhole_terms(const Eigen::Vector2d& xy, Eigen::Vector2d& tangential) const {
  const auto& d = calibration_.distortion;  // k1 k2 p1 p2 k3
  const double x = xy.x();
  const double y = xy.y();
  const double r2 = x * x + y * y;
  tangential = {2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x), d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y};
  return 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
}

Eigen::Vector2d Lens::pinhole_distort(const Eigen::Vector2d& xy) const {
  Eigen::Vector2d tangential;
  const double radial = pinhole_terms(xy, tangential);
  return xy * radial + tangential;
}

std::optional<Eigen::Vector2d> Lens::project(const Eigen::Vector3d& point) const {
  Eigen::Vector2d distorted;
  if (fisheye_) {
    const double r = std::hypot(point.x(), point.y());
    const double theta = std::atan2(r, point.z());
    if (!(theta <= max_field_angle_rad_)) return std::nullopt;
    distorted = r < 1e-300 ? Eigen::Vector2d::Zero() : Eigen::Vector2d(point.head<2>() * (fisheye_distort(theta) / r));
  } else {
    if (!(point.z() > 0.0)) return std::nullopt;
    const Eigen::Vector2d xy = point.head<2>() / point.z();
    if (std::atan(xy.norm()) > max_field_angle_rad_) return std::nullopt;
    distorted = pinhole_distort(xy);
  }
  return Eigen::Vector2d(calibration_.fx * distorted.x() + calibration_.cx,
                         calibration_.fy * distorted.y() + calibration_.cy);
}

std::optional<Eigen::Vector3d> Lens::unproject(double u, double v) const {
  const double x = (u - calibration_.cx) / calibration_.fx;
  const double y = (v - calibration_.cy) / calibration_.fy;
  if (!fisheye_) {
    // Fixed-point inversion of the distortion (as OpenCV's undistortPoints), then checked.
    const Eigen::Vector2d target(x, y);
    Eigen::Vector2d xy = target;
    Eigen::Vector2d tangential;
    for (int it = 0; it < 50; ++it) {
      const double radial = pinhole_terms(xy, tangential);
      const Eigen::Vector2d next = (target - tangential) / radial;
      const double moved = (next - xy).squaredNorm();
      xy = next;
      if (moved < 1e-26) break;
    }
    if (!xy.allFinite() || (pinhole_distort(xy) - target).norm() > 1e-9 ||
        std::atan(xy.norm()) > max_field_angle_rad_) {
      return std::nullopt;
    }
    return Eigen::Vector3d(xy.x(), xy.y(), 1.0).normalized();
  }
  // Invert θ_d(θ) by Newton's method.
  const auto& k = calibration_.distortion;
  const double theta_d = std::hypot(x, y);
  double theta = theta_d;
  for (int it = 0; it < 50; ++it) {
    const double t2 = theta * theta;
    const double df = 1 + t2 * (3 * k[0] + t2 * (5 * k[1] + t2 * (7 * k[2] + t2 * 9 * k[3])));
    const double step = (fisheye_distort(theta) - theta_d) / df;
    theta -= step;
    if (std::abs(step) < 1e-13) break;
  }
  if (!(theta >= 0.0) || theta > max_field_angle_rad_ || std::abs(fisheye_distort(theta) - theta_d) > 1e-9) {
    return std::nullopt;
  }
  if (theta_d < 1e-12) return Eigen::Vector3d(0.0, 0.0, 1.0);
  return Eigen::Vector3d(std::sin(theta) * x / theta_d, std::sin(theta) * y / theta_d, std::cos(theta));
}

}  // namespace rankslam::camera
