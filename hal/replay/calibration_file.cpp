#include "rankslam/replay/calibration_file.hpp"

#include "rankslam/yaml/strict_yaml.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <limits>
#include <set>

namespace rankslam::replay {
namespace {

namespace fs = std::filesystem;

// The keys the writers emit (record::calibration_yaml, the simulator's); any other is a typo.
const std::set<std::string> kRootKeys = {"depth_scale", "depth_noise_per_m", "cameras", "wheels"};
const std::set<std::string> kCameraNames = {"rgb", "fisheye"};
const std::set<std::string> kCameraKeys = {"model",      "width",      "height",           "intrinsics",
                                           "distortion", "T_base_cam", "field_of_view_deg"};
const std::set<std::string> kPoseKeys = {"translation", "rotation_xyzw"};
const std::set<std::string> kWheelKeys = {"radius_m", "track_width_m", "ticks_per_revolution", "can_id"};

constexpr double kLowest = std::numeric_limits<double>::lowest();
constexpr double kHighest = std::numeric_limits<double>::max();

std::string key_path(const std::string& where, const std::string& key) { return where.empty() ? key : where + "." + key; }

// Reads the required number map[key], finite and within [min, max], naming the key path on failure.
template <typename T>
std::string read_field(const YAML::Node& map, const std::string& key, const std::string& where, T min, T max, T& value) {
  const YAML::Node field = map[key];
  if (!field) return key_path(where, key) + " is missing";
  return yaml::read_number(field, key_path(where, key), min, max, value);
}

// Reads the list map[key] of min_size to N numbers, each finite and within [min, max].
template <std::size_t N>
std::string read_array(const YAML::Node& map, const std::string& key, const std::string& where, std::size_t min_size,
                       double min, double max, std::array<double, N>& values) {
  const std::string path = key_path(where, key);
  const YAML::Node field = map[key];
  if (!field) return path + " is missing";
  if (!field.IsSequence() || field.size() < min_size || field.size() > N) {
    return path + " must be a list of " + std::to_string(min_size) +
           (min_size == N ? "" : " to " + std::to_string(N)) + " numbers" + yaml::at(field.Mark());
  }
  values.fill(0.0);
  for (std::size_t i = 0; i < field.size(); ++i) {
    if (auto error = yaml::read_number(field[i], path + "[" + std::to_string(i) + "]", min, max, values[i]);
        !error.empty()) {
      return error;
    }
  }
  return {};
}

std::string read_pose(const YAML::Node& node, const std::string& where, Eigen::Isometry3d& pose) {
  if (auto error = yaml::check_map(node, where, kPoseKeys); !error.empty()) return error;
  std::array<double, 3> translation{};
  std::array<double, 4> rotation_xyzw{};
  // A mounting farther than 100 m from the base is a unit mistake (millimetres for metres).
  if (auto error = read_array(node, "translation", where, 3, -100.0, 100.0, translation); !error.empty()) return error;
  if (auto error = read_array(node, "rotation_xyzw", where, 4, kLowest, kHighest, rotation_xyzw); !error.empty()) {
    return error;
  }
  Eigen::Quaterniond q(rotation_xyzw[3], rotation_xyzw[0], rotation_xyzw[1], rotation_xyzw[2]);
  if (!(std::abs(q.norm() - 1.0) <= 1e-3)) return where + ".rotation_xyzw is not a unit quaternion";
  pose = Eigen::Isometry3d::Identity();
  pose.linear() = q.normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(translation[0], translation[1], translation[2]);
  return {};
}

std::string read_camera(const YAML::Node& node, const std::string& where, hal::CameraCalibration& camera) {
  if (auto error = yaml::check_map(node, where, kCameraKeys); !error.empty()) return error;
  const YAML::Node model_node = node["model"];
  if (!model_node) return where + ".model is missing";
  const std::string model = model_node.IsScalar() ? model_node.Scalar() : std::string();
  if (model == "pinhole") {
    camera.model = hal::CameraModel::kPinhole;
  } else if (model == "fisheye") {
    camera.model = hal::CameraModel::kFisheye;
  } else {
    return where + ".model must be 'pinhole' or 'fisheye', not '" + model + "'";
  }
  if (auto error = read_field(node, "width", where, 1, 8192, camera.width); !error.empty()) return error;
  if (auto error = read_field(node, "height", where, 1, 8192, camera.height); !error.empty()) return error;
  std::array<double, 4> intrinsics{};
  if (auto error = read_array(node, "intrinsics", where, 4, kLowest, kHighest, intrinsics); !error.empty()) return error;
  camera.fx = intrinsics[0];
  camera.fy = intrinsics[1];
  camera.cx = intrinsics[2];
  camera.cy = intrinsics[3];
  const double width = camera.width;
  const double height = camera.height;
  // fx = (width / 2) / tan(fov / 2): 0.05 x width is a 169 deg pinhole view, 100 x width a 0.6 deg one.
  const std::string intrinsics_path = where + ".intrinsics";
  if (auto error = yaml::check_range(camera.fx, intrinsics_path + "[0] (fx)", 0.05 * width, 100.0 * width);
      !error.empty()) {
    return error;
  }
  if (auto error = yaml::check_range(camera.fy, intrinsics_path + "[1] (fy)", 0.05 * width, 100.0 * width);
      !error.empty()) {
    return error;
  }
  // The principal point lies in the image, or at most one image size beside it (a cropped sensor).
  if (auto error = yaml::check_range(camera.cx, intrinsics_path + "[2] (cx)", -width, 2.0 * width); !error.empty()) {
    return error;
  }
  if (auto error = yaml::check_range(camera.cy, intrinsics_path + "[3] (cy)", -height, 2.0 * height); !error.empty()) {
    return error;
  }
  if (node["distortion"]) {
    // Real lenses' coefficients stay within a few units; 100 is far outside any of them.
    if (auto error = read_array(node, "distortion", where, camera.model == hal::CameraModel::kFisheye ? 4 : 5, -100.0,
                                100.0, camera.distortion);
        !error.empty()) {
      return error;
    }
  }
  if (node["T_base_cam"]) {
    if (auto error = read_pose(node["T_base_cam"], where + ".T_base_cam", camera.T_base_cam); !error.empty()) {
      return error;
    }
    camera.T_base_cam_given = true;
  }
  if (node["field_of_view_deg"]) {
    if (auto error = read_field(node, "field_of_view_deg", where, 1.0, 360.0, camera.field_of_view_deg);
        !error.empty()) {
      return error;
    }
  }
  return {};
}

std::string read_wheels(const YAML::Node& node, hal::WheelGeometry& geometry) {
  if (auto error = yaml::check_map(node, "wheels", kWheelKeys); !error.empty()) return error;
  if (auto error = read_field(node, "radius_m", "wheels", 0.001, 10.0, geometry.radius_m); !error.empty()) return error;
  if (auto error = read_field(node, "track_width_m", "wheels", 0.01, 100.0, geometry.track_width_m); !error.empty()) {
    return error;
  }
  if (auto error = read_field(node, "ticks_per_revolution", "wheels", 1, 100'000'000, geometry.ticks_per_revolution);
      !error.empty()) {
    return error;
  }
  // Wheel frames are classic CAN frames: an 11-bit identifier.
  if (node["can_id"]) return read_field(node, "can_id", "wheels", 0U, 0x7FFU, geometry.can_id);
  return {};
}

std::string read_calibration(const YAML::Node& root, hal::Calibration& calibration) {
  if (auto error = yaml::check_map(root, "", kRootKeys); !error.empty()) return error;
  if (root["depth_scale"]) {
    // Raw units per metre: 1 (metres) .. 1e6 (micrometres); TUM 5000, OpenNI 1000.
    if (auto error = read_field(root, "depth_scale", "", 1.0, 1e6, calibration.depth_scale); !error.empty()) {
      return error;
    }
  }
  if (root["depth_noise_per_m"]) {
    if (auto error = read_field(root, "depth_noise_per_m", "", 0.0, 0.1, calibration.depth_noise_per_m);
        !error.empty()) {
      return error;
    }
  }
  const YAML::Node cameras = root["cameras"];
  if (!cameras) return "cameras.rgb is missing";
  if (auto error = yaml::check_map(cameras, "cameras", kCameraNames); !error.empty()) return error;
  if (!cameras["rgb"]) return "cameras.rgb is missing";
  if (auto error = read_camera(cameras["rgb"], "cameras.rgb", calibration.rgb); !error.empty()) return error;
  if (cameras["fisheye"]) {
    hal::CameraCalibration fisheye;
    if (auto error = read_camera(cameras["fisheye"], "cameras.fisheye", fisheye); !error.empty()) return error;
    calibration.fisheye = fisheye;
  }
  if (const YAML::Node wheels = root["wheels"]) {
    hal::WheelGeometry geometry;
    if (auto error = read_wheels(wheels, geometry); !error.empty()) return error;
    calibration.wheels = geometry;
  }
  return {};
}

}  // namespace

std::string load_calibration_yaml(const fs::path& path, hal::Calibration& calibration) {
  YAML::Node root;
  if (auto error = yaml::load_file(path, root); !error.empty()) return path.string() + ": " + error;
  calibration = hal::Calibration{};
  calibration.source = path.string();
  if (auto error = read_calibration(root, calibration); !error.empty()) return path.string() + ": " + error;
  return {};
}

std::string read_mounting(const YAML::Node& node, const std::string& where, Eigen::Isometry3d& T_base_cam) {
  return read_pose(node, where, T_base_cam);
}

}  // namespace rankslam::replay
