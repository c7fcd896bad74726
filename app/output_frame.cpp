#include "output_frame.hpp"

#include "rankslam/core/units.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rankslam::app {

const char* to_string(OutputFrame frame) { return frame == OutputFrame::kBase ? "base" : "camera"; }

std::string choose_output_frame(std::string_view requested, bool mounting_known, OutputFrame& frame) {
  if (requested.empty()) {
    frame = mounting_known ? OutputFrame::kBase : OutputFrame::kCamera;
    return {};
  }
  if (requested == "camera") {
    frame = OutputFrame::kCamera;
    return {};
  }
  if (requested == "base") {
    if (!mounting_known) {
      return "--frame base needs the camera mounting: the calibration gives no cameras.rgb.T_base_cam";
    }
    frame = OutputFrame::kBase;
    return {};
  }
  return "--frame must be camera or base, not '" + std::string(requested) + "'";
}

eval::Trajectory in_output_frame(const eval::Trajectory& camera_poses, OutputFrame frame,
                                 const Eigen::Isometry3d& T_base_cam) {
  if (frame == OutputFrame::kCamera) return camera_poses;
  const Eigen::Isometry3d T_cam_base = T_base_cam.inverse();
  eval::Trajectory base_poses;
  base_poses.reserve(camera_poses.size());
  for (const eval::StampedPose& pose : camera_poses) {
    base_poses.push_back({pose.stamp_s, T_base_cam * pose.T_world_cam * T_cam_base});
  }
  return base_poses;
}

Eigen::Isometry3d output_from_world(OutputFrame frame, const Eigen::Isometry3d& T_base_cam) {
  return frame == OutputFrame::kBase ? T_base_cam : Eigen::Isometry3d::Identity();
}

std::string describe_mounting(const Eigen::Isometry3d& T_base_cam) {
  const Eigen::Vector3d t = T_base_cam.translation();
  // Roll, pitch, yaw of the optical frame in the base (Z-Y-X); a camera looking ahead, level, is -90 0 -90.
  const Eigen::Matrix3d R = T_base_cam.linear();
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double pitch = -std::asin(std::clamp(R(2, 0), -1.0, 1.0));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  // Rounded to what is printed, so that -0.0001 prints as 0.000, not -0.000.
  const auto shown = [](double value, double step) { return std::round(value / step) * step + 0.0; };
  char text[160];
  std::snprintf(text, sizeof text, "translation [%.3f, %.3f, %.3f] m, roll pitch yaw [%.1f, %.1f, %.1f] deg",
                shown(t.x(), 1e-3), shown(t.y(), 1e-3), shown(t.z(), 1e-3), shown(rad_to_deg(roll), 0.1),
                shown(rad_to_deg(pitch), 0.1), shown(rad_to_deg(yaw), 0.1));
  return text;
}

}  // namespace rankslam::app
