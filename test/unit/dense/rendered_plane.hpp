#pragma once

// A textured plane seen by a pinhole RGB-D camera, rendered exactly: the dense aligner's tests
// know the true motion between two views of it.

#include "rankslam/camera/depth_camera.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <cmath>
#include <cstdint>

namespace rankslam::dense::test {

inline constexpr double kDepthScale = 5000.0;  // raw units per metre (TUM's)

inline hal::CameraCalibration plane_camera() {
  hal::CameraCalibration c;
  c.width = 320;
  c.height = 240;
  c.fx = c.fy = 262.5;
  c.cx = 159.5;
  c.cy = 119.5;
  return c;
}

/// Grey image and raw depth of the plane n·X = d (reference-frame X) seen from T_ref_cam;
/// `textured` false gives a uniform grey plane.
inline void render_plane(const hal::CameraCalibration& c, const Eigen::Isometry3d& T_ref_cam, bool textured,
                         cv::Mat& grey, cv::Mat& depth) {
  const Eigen::Vector3d n = Eigen::Vector3d(0.25, -0.15, 1.0).normalized();
  const double d = 1.8;
  grey.create(c.height, c.width, CV_8UC1);
  depth.create(c.height, c.width, CV_16UC1);
  for (int v = 0; v < c.height; ++v) {
    for (int u = 0; u < c.width; ++u) {
      const Eigen::Vector3d ray((u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0);
      const Eigen::Vector3d dir = T_ref_cam.linear() * ray;
      const Eigen::Vector3d origin = T_ref_cam.translation();
      const double s = (d - n.dot(origin)) / n.dot(dir);  // the camera-frame depth (ray.z = 1)
      const Eigen::Vector3d X = origin + s * dir;
      const double value = textured ? 128.0 + 50.0 * std::sin(9.0 * X.x()) * std::cos(7.0 * X.y()) +
                                          35.0 * std::sin(23.0 * (X.x() + 0.6 * X.y())) + 15.0 * std::cos(41.0 * X.y())
                                    : 128.0;
      grey.at<std::uint8_t>(v, u) = cv::saturate_cast<std::uint8_t>(value);
      depth.at<std::uint16_t>(v, u) = cv::saturate_cast<std::uint16_t>(s * kDepthScale);
    }
  }
}

inline Eigen::Isometry3d motion(double angle_deg, const Eigen::Vector3d& axis, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(angle_deg * M_PI / 180.0, axis.normalized()).toRotationMatrix();
  T.translation() = t;
  return T;
}

inline double angle_deg(const Eigen::Isometry3d& T) { return Eigen::AngleAxisd(T.linear()).angle() * 180.0 / M_PI; }

}  // namespace rankslam::dense::test
