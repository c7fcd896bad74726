#include "rankslam/record/recording_writer.hpp"

#include <Eigen/Geometry>

#include <cstdio>
#include <initializer_list>

namespace rankslam::record {
namespace {

std::string number(double value) {
  char text[48];
  std::snprintf(text, sizeof text, "%.10g", value);
  return text;
}

std::string list(std::initializer_list<double> values) {
  std::string text = "[";
  bool first = true;
  for (const double v : values) {
    text += (first ? "" : ", ") + number(v);
    first = false;
  }
  return text + "]";
}

std::string camera_yaml(const char* name, const hal::CameraCalibration& camera) {
  const bool fisheye = camera.model == hal::CameraModel::kFisheye;
  const auto& d = camera.distortion;
  std::string text = std::string("  ") + name + ":\n";
  text += std::string("    model: ") + (fisheye ? "fisheye" : "pinhole") + "\n";
  text += "    width: " + std::to_string(camera.width) + "\n";
  text += "    height: " + std::to_string(camera.height) + "\n";
  text += "    intrinsics: " + list({camera.fx, camera.fy, camera.cx, camera.cy}) + "  # fx fy cx cy\n";
  text += "    distortion: " +
          (fisheye ? list({d[0], d[1], d[2], d[3]}) + "  # k1 k2 k3 k4\n" : list({d[0], d[1], d[2], d[3], d[4]}) + "  # k1 k2 p1 p2 k3\n");
  if (camera.field_of_view_deg > 0.0) text += "    field_of_view_deg: " + number(camera.field_of_view_deg) + "\n";
  if (!camera.T_base_cam_given) return text;  // an unknown mounting stays unknown in the recording
  const Eigen::Vector3d t = camera.T_base_cam.translation();
  Eigen::Quaterniond q(camera.T_base_cam.linear());
  q.normalize();
  text += "    T_base_cam:\n";
  text += "      translation: " + list({t.x(), t.y(), t.z()}) + "\n";
  text += "      rotation_xyzw: " + list({q.x(), q.y(), q.z(), q.w()}) + "\n";
  return text;
}

}  // namespace

std::string calibration_yaml(const hal::Calibration& calibration, const std::string& comment) {
  std::string text = "# rankslam recording calibration: " + comment + "\n";
  text += "# source: " + calibration.source + "\n";
  text += "depth_scale: " + number(calibration.depth_scale) + "  # raw depth units per metre\n";
  text += "depth_noise_per_m: " + number(calibration.depth_noise_per_m) + "  # a in the axial depth noise a*z^2\n";
  text += "cameras:\n";
  text += camera_yaml("rgb", calibration.rgb);
  if (calibration.fisheye) text += camera_yaml("fisheye", *calibration.fisheye);
  if (calibration.wheels) {
    char id[32];
    std::snprintf(id, sizeof id, "0x%X", calibration.wheels->can_id);
    text += "wheels:\n";
    text += "  radius_m: " + number(calibration.wheels->radius_m) + "\n";
    text += "  track_width_m: " + number(calibration.wheels->track_width_m) + "\n";
    text += "  ticks_per_revolution: " + std::to_string(calibration.wheels->ticks_per_revolution) + "\n";
    text += std::string("  can_id: ") + id + "\n";
  }
  return text;
}

}  // namespace rankslam::record
