#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/sim/simulator.hpp"

#include <Eigen/Geometry>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace rankslam::sim::testing {

namespace fs = std::filesystem;

/// A fresh, absent folder under the system temp dir; removed with everything in it.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    static std::atomic<int> counter{0};
    path_ = fs::temp_directory_path() /
            ("rankslam_sim_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
    fs::remove_all(path_);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const fs::path& path() const { return path_; }
  [[nodiscard]] fs::path operator/(const std::string& name) const { return path_ / name; }

 private:
  fs::path path_;
};

inline SimulationOptions options_for(const std::string& scene, const fs::path& dir, int frames) {
  SimulationOptions options;
  options.scene = scene;
  options.out_dir = dir;
  options.frames = frames;
  return options;
}

/// Non-comment lines of a text file, split on white space.
inline std::vector<std::vector<std::string>> read_rows(const fs::path& path) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::vector<std::string> row;
    std::string field;
    while (fields >> field) row.push_back(field);
    rows.push_back(row);
  }
  return rows;
}

/// Image `index` of a recording's list (`rgb.txt`, `depth.txt`, ...), read with `flags`.
inline cv::Mat image_of(const fs::path& dir, const std::string& list, std::size_t index, int flags) {
  const auto rows = read_rows(dir / list);
  return cv::imread((dir / rows.at(index).at(1)).string(), flags);
}

inline std::vector<std::string> read_all_lines(const fs::path& path) {
  std::vector<std::string> lines;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) lines.push_back(line);
  return lines;
}

inline std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  std::string bytes(static_cast<std::size_t>(std::max<std::streamoff>(in.tellg(), 0)), '\0');
  in.seekg(0);
  in.read(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return bytes;
}

struct StampedPose {
  double stamp_s = 0.0;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
};

inline std::vector<StampedPose> read_groundtruth(const fs::path& path) {
  std::vector<StampedPose> poses;
  for (const auto& row : read_rows(path)) {
    if (row.size() != 8) continue;
    StampedPose pose;
    pose.stamp_s = std::stod(row[0]);
    const Eigen::Quaterniond q(std::stod(row[7]), std::stod(row[4]), std::stod(row[5]), std::stod(row[6]));
    pose.T.linear() = q.normalized().toRotationMatrix();
    pose.T.translation() = Eigen::Vector3d(std::stod(row[1]), std::stod(row[2]), std::stod(row[3]));
    poses.push_back(pose);
  }
  return poses;
}

inline Eigen::Isometry3d read_pose(const YAML::Node& node) {
  const auto t = node["translation"].as<std::vector<double>>();
  const auto q = node["rotation_xyzw"].as<std::vector<double>>();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(q.at(3), q.at(0), q.at(1), q.at(2)).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(t.at(0), t.at(1), t.at(2));
  return T;
}

inline hal::CameraCalibration read_camera(const YAML::Node& node) {
  hal::CameraCalibration camera;
  camera.model = node["model"].as<std::string>() == "fisheye" ? hal::CameraModel::kFisheye : hal::CameraModel::kPinhole;
  camera.width = node["width"].as<int>();
  camera.height = node["height"].as<int>();
  const auto k = node["intrinsics"].as<std::vector<double>>();
  camera.fx = k.at(0);
  camera.fy = k.at(1);
  camera.cx = k.at(2);
  camera.cy = k.at(3);
  const auto d = node["distortion"].as<std::vector<double>>();
  for (std::size_t i = 0; i < d.size() && i < camera.distortion.size(); ++i) camera.distortion[i] = d[i];
  camera.T_base_cam = read_pose(node["T_base_cam"]);
  return camera;
}

/// calibration.yaml read independently of the product's reader, with yaml-cpp.
inline hal::Calibration read_calibration(const fs::path& path) {
  const YAML::Node root = YAML::LoadFile(path.string());
  hal::Calibration calibration;
  calibration.depth_scale = root["depth_scale"].as<double>();
  calibration.rgb = read_camera(root["cameras"]["rgb"]);
  if (root["cameras"]["fisheye"]) calibration.fisheye = read_camera(root["cameras"]["fisheye"]);
  if (root["wheels"]) {
    hal::WheelGeometry wheels;
    wheels.radius_m = root["wheels"]["radius_m"].as<double>();
    wheels.track_width_m = root["wheels"]["track_width_m"].as<double>();
    wheels.ticks_per_revolution = root["wheels"]["ticks_per_revolution"].as<int>();
    wheels.can_id = root["wheels"]["can_id"].as<unsigned>();
    calibration.wheels = wheels;
  }
  return calibration;
}

/// Camera-frame point of pixel (u, v) with depth z (pinhole, no distortion).
inline Eigen::Vector3d back_project(const hal::CameraCalibration& camera, double u, double v, double z) {
  return {(u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z};
}

/// Yaw of a base frame (x forward) in a z-up world.
inline double yaw_of(const Eigen::Isometry3d& T_world_base) {
  const Eigen::Vector3d x = T_world_base.linear().col(0);
  return std::atan2(x.y(), x.x());
}

}  // namespace rankslam::sim::testing
