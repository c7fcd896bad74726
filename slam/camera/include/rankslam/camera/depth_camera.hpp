#pragma once

#include "rankslam/hal/calibration.hpp"

#include <Eigen/Core>

#include <algorithm>
#include <memory>
#include <vector>

namespace rankslam::camera {

/// Back-projection for the RGB-D camera. Depth is registered to the (distorted) colour image, so
/// a pixel's ray comes from undoing the lens distortion; a table built at set-up holds the
/// normalised undistorted coordinates of every pixel, making back-projection a lookup. Copies
/// share the table (it never changes): each part keeping its own model costs no memory.
class DepthCameraModel {
 public:
  DepthCameraModel() = default;
  DepthCameraModel(const hal::CameraCalibration& calibration, double depth_scale,
                   double depth_noise_per_m = hal::Calibration{}.depth_noise_per_m);
  /// The colour camera of `calibration` with its registered depth.
  explicit DepthCameraModel(const hal::Calibration& calibration)
      : DepthCameraModel(calibration.rgb, calibration.depth_scale, calibration.depth_noise_per_m) {}

  [[nodiscard]] int width() const { return width_; }
  [[nodiscard]] int height() const { return height_; }
  [[nodiscard]] double depth_scale() const { return depth_scale_; }
  /// a in the depth sensor's axial noise σ_z = a·z² (hal::Calibration::depth_noise_per_m).
  [[nodiscard]] double depth_noise_per_m() const { return depth_noise_per_m_; }
  [[nodiscard]] const hal::CameraCalibration& calibration() const { return calibration_; }

  /// Normalised undistorted ray (x/z, y/z) through pixel (u, v), both integers in range.
  [[nodiscard]] Eigen::Vector2f ray(int u, int v) const {
    return ray_data_[static_cast<std::size_t>(v) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(u)];
  }
  /// Ray through a sub-pixel position, bilinear between the table's pixels; (u, v) must lie in
  /// [0, width - 1] × [0, height - 1].
  [[nodiscard]] Eigen::Vector2f ray(float u, float v) const {
    const int u0 = std::min(static_cast<int>(u), width_ - 2);
    const int v0 = std::min(static_cast<int>(v), height_ - 2);
    const float a = u - static_cast<float>(u0);
    const float b = v - static_cast<float>(v0);
    return (1.0F - b) * ((1.0F - a) * ray(u0, v0) + a * ray(u0 + 1, v0)) +
           b * ((1.0F - a) * ray(u0, v0 + 1) + a * ray(u0 + 1, v0 + 1));
  }
  /// Camera-frame point of pixel (u, v) at depth z_m.
  [[nodiscard]] Eigen::Vector3f back_project(int u, int v, float z_m) const {
    const Eigen::Vector2f r = ray(u, v);
    return {r.x() * z_m, r.y() * z_m, z_m};
  }
  /// Metres of a raw depth value.
  [[nodiscard]] float metres(unsigned short raw) const { return static_cast<float>(raw) * metres_per_unit_; }

 private:
  hal::CameraCalibration calibration_;
  int width_ = 0;
  int height_ = 0;
  double depth_scale_ = 5000.0;
  double depth_noise_per_m_ = 0.0;
  float metres_per_unit_ = 1.0F / 5000.0F;
  std::shared_ptr<const std::vector<Eigen::Vector2f>> rays_;
  const Eigen::Vector2f* ray_data_ = nullptr;  ///< rays_->data(), held for the lookups
};

}  // namespace rankslam::camera
