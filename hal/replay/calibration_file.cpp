#include "rankslam/replay/calibration_file.hpp"

#include <yaml-cpp/yaml.h>

#include <array>
#include <cmath>

namespace rankslam::replay {
namespace {

namespace fs = std::filesystem;

// Reads a required number from a YAML map, naming the field path on failure.
template <typename T>
std::string read_field(const YAML::Node& node, const std::string& key, const std::string& where, T& value) {
  const YAML::Node field = node[key];
  if (!field) return where + "." + key + " is missing";
  try {
    value = field.as<T>();
  } catch (const YAML::Exception&) {
    return where + "." + key + " is not a valid value";
  }
  return {};
}

template <std::size_t N>
std::string read_array(const YAML::Node& node, const std::string& key, const std::string& where,
                       std::size_t min_size, std::array<double, N>& values) {
  const YAML::Node field = node[key];
  if (!field) return where + "." + key + " is missing";
  if (!field.IsSequence() || field.size() < min_size || field.size() > N) {
    return where + "." + key + " must be a list of " + std::to_string(min_size) +
           (min_size == N ? "" : " to " + std::to_string(N)) + " numbers";
  }
  values.fill(0.0);
  try {
    for (std::size_t i = 0; i < field.size(); ++i) values[i] = field[i].as<double>();
  } catch (const YAML::Exception&) {
    return where + "." + key + " holds a value that is not a number";
  }
  return {};
}

std::string read_pose(const YAML::Node& node, const std::string& where, Eigen::Isometry3d& pose) {
  std::array<double, 3> translation{};
  std::array<double, 4> rotation_xyzw{};
  if (auto error = read_array(node, "translation", where, 3, translation); !error.empty()) return error;
  if (auto error = read_array(node, "rotation_xyzw", where, 4, rotation_xyzw); !error.empty()) return error;
  Eigen::Quaterniond q(rotation_xyzw[3], rotation_xyzw[0], rotation_xyzw[1], rotation_xyzw[2]);
  if (std::abs(q.norm() - 1.0) > 1e-3) return where + ".rotation_xyzw is not a unit quaternion";
  pose = Eigen::Isometry3d::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(translation[0], translation[1], translation[2]);
  return {};
}

std::string read_camera(const YAML::Node& node, const std::string& where, hal::CameraCalibration& camera) {
  std::string model;
  if (auto error = read_field(node, "model", where, model); !error.empty()) return error;
  if (model == "pinhole") {
    camera.model = hal::CameraModel::kPinhole;
  } else if (model == "fisheye") {
    camera.model = hal::CameraModel::kFisheye;
  } else {
    return where + ".model must be 'pinhole' or 'fisheye', not '" + model + "'";
  }
  if (auto error = read_field(node, "width", where, camera.width); !error.empty()) return error;
  if (auto error = read_field(node, "height", where, camera.height); !error.empty()) return error;
  if (camera.width <= 0 || camera.height <= 0 || camera.width > 8192 || camera.height > 8192) {
    return where + ".width/height must be 1..8192";
  }
  std::array<double, 4> intrinsics{};
  if (auto error = read_array(node, "intrinsics", where, 4, intrinsics); !error.empty()) return error;
  camera.fx = intrinsics[0];
  camera.fy = intrinsics[1];
  camera.cx = intrinsics[2];
  camera.cy = intrinsics[3];
  if (!(camera.fx > 0.0) || !(camera.fy > 0.0)) return where + ".intrinsics: fx and fy must be positive";
  if (node["distortion"]) {
    if (auto error = read_array(node, "distortion", where, camera.model == hal::CameraModel::kFisheye ? 4 : 5,
                                camera.distortion);
        !error.empty()) {
      return error;
    }
  }
  if (node["T_base_cam"]) {
    if (auto error = read_pose(node["T_base_cam"], where + ".T_base_cam", camera.T_base_cam); !error.empty()) {
      return error;
    }
  }
  return {};
}

}  // namespace

std::string load_calibration_yaml(const fs::path& path, hal::Calibration& calibration) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::Exception& error) {
    return path.string() + ": " + error.what();
  }
  const std::string where = path.string() + ": ";
  calibration = hal::Calibration{};
  calibration.source = path.string();
  if (root["depth_scale"]) {
    if (auto error = read_field(root, "depth_scale", "calibration", calibration.depth_scale); !error.empty()) {
      return where + "depth_scale is not a number";
    }
  }
  if (!(calibration.depth_scale > 0.0)) return where + "depth_scale must be positive";
  if (root["depth_noise_per_m"]) {
    if (auto error = read_field(root, "depth_noise_per_m", "calibration", calibration.depth_noise_per_m);
        !error.empty()) {
      return where + "depth_noise_per_m is not a number";
    }
  }
  if (!(calibration.depth_noise_per_m >= 0.0 && calibration.depth_noise_per_m <= 0.1)) {
    return where + "depth_noise_per_m must lie in 0 .. 0.1";
  }
  const YAML::Node cameras = root["cameras"];
  if (!cameras || !cameras["rgb"]) return where + "cameras.rgb is missing";
  if (auto error = read_camera(cameras["rgb"], "cameras.rgb", calibration.rgb); !error.empty()) return where + error;
  if (cameras["fisheye"]) {
    hal::CameraCalibration fisheye;
    if (auto error = read_camera(cameras["fisheye"], "cameras.fisheye", fisheye); !error.empty()) return where + error;
    calibration.fisheye = fisheye;
  }
  if (const YAML::Node wheels = root["wheels"]) {
    hal::WheelGeometry geometry;
    if (auto error = read_field(wheels, "radius_m", "wheels", geometry.radius_m); !error.empty()) return where + error;
    if (auto error = read_field(wheels, "track_width_m", "wheels", geometry.track_width_m); !error.empty()) {
      return where + error;
    }
    if (auto error = read_field(wheels, "ticks_per_revolution", "wheels", geometry.ticks_per_revolution);
        !error.empty()) {
      return where + error;
    }
    if (wheels["can_id"]) {
      if (auto error = read_field(wheels, "can_id", "wheels", geometry.can_id); !error.empty()) return where + error;
    }
    if (!(geometry.radius_m > 0.0) || !(geometry.track_width_m > 0.0) || geometry.ticks_per_revolution <= 0) {
      return where + "wheels: radius_m, track_width_m and ticks_per_revolution must be positive";
    }
    calibration.wheels = geometry;
  }
  return {};
}

}  // namespace rankslam::replay
