#pragma once

#include "rankslam/hal/calibration.hpp"

#include <Eigen/Core>

#include <optional>

namespace rankslam::camera {

/// A camera's projection through its lens: OpenCV's pinhole model with radial-tangential
/// distortion (k1 k2 p1 p2 k3) or its fisheye model (equidistant, θ_d = θ(1 + k1θ² + k2θ⁴ + k3θ⁶
/// + k4θ⁸)). The fisheye branch takes the angle from the optical axis with atan2, so rays beyond
/// 90° (a 190° lens) project where OpenCV's fisheye functions, which divide by z, cannot.
class Lens {
 public:
  /// `max_field_angle_rad` ≤ 0: the largest angle from the optical axis up to which the model's
  /// distortion still grows with the angle (π for a fisheye without such a turn, just under π/2
  /// for a pinhole), so that projection is one-to-one and unprojection has one answer; within
  /// half the calibration's `field_of_view_deg` where that is given.
  explicit Lens(const hal::CameraCalibration& calibration, double max_field_angle_rad = 0.0);

  /// Pixel of a point in the camera's optical frame; none beyond the field angle or, for a
  /// pinhole, behind the camera. The pixel may lie outside the image.
  [[nodiscard]] std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& point) const;
  /// Unit ray through pixel (u, v); none where no ray within the field angle reaches it.
  [[nodiscard]] std::optional<Eigen::Vector3d> unproject(double u, double v) const;

  [[nodiscard]] double max_field_angle_rad() const { return max_field_angle_rad_; }
  [[nodiscard]] const hal::CameraCalibration& calibration() const { return calibration_; }

 private:
  /// Fisheye: θ_d of θ.
  [[nodiscard]] double fisheye_distort(double theta) const;
  /// Pinhole: the radial factor at normalised point xy, and its tangential shift.
  [[nodiscard]] double pinhole_terms(const Eigen::Vector2d& xy, Eigen::Vector2d& tangential) const;
  /// Pinhole: xy · radial + tangential.
  [[nodiscard]] Eigen::Vector2d pinhole_distort(const Eigen::Vector2d& xy) const;

  hal::CameraCalibration calibration_;
  bool fisheye_ = false;
  double max_field_angle_rad_ = 0.0;
};

}  // namespace rankslam::camera
