#include "rankslam/replay/recording.hpp"

#include "rankslam/hal/associate.hpp"
#include "rankslam/hal/candump.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

namespace rankslam::replay {
namespace {

namespace fs = std::filesystem;

struct StampedFile {
  double stamp_s = 0.0;
  std::string file;
};

bool is_comment_or_blank(const std::string& line) {
  const auto first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

// Reads a "timestamp filename" list (rgb.txt, depth.txt, ir.txt, fisheye.txt).
std::string read_stamped_list(const fs::path& path, std::vector<StampedFile>& entries) {
  std::ifstream in(path);
  if (!in) return "cannot open " + path.string();
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (is_comment_or_blank(line)) continue;
    std::istringstream fields(line);
    StampedFile entry;
    if (!(fields >> entry.stamp_s >> entry.file) || !std::isfinite(entry.stamp_s)) {
      return path.string() + ":" + std::to_string(line_number) + ": expected 'timestamp filename'";
    }
    entries.push_back(std::move(entry));
  }
  return {};
}

std::string read_associations(const fs::path& path, std::vector<FrameEntry>& frames) {
  std::ifstream in(path);
  if (!in) return "cannot open " + path.string();
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (is_comment_or_blank(line)) continue;
    std::istringstream fields(line);
    FrameEntry frame;
    if (!(fields >> frame.rgb_stamp_s >> frame.rgb_file >> frame.depth_stamp_s >> frame.depth_file)) {
      return path.string() + ":" + std::to_string(line_number) +
             ": expected 'rgb_stamp rgb_file depth_stamp depth_file'";
    }
    frames.push_back(std::move(frame));
  }
  return {};
}

std::vector<double> stamps_of(const std::vector<StampedFile>& entries) {
  std::vector<double> stamps;
  stamps.reserve(entries.size());
  for (const auto& entry : entries) stamps.push_back(entry.stamp_s);
  return stamps;
}

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

// The TUM camera named by a folder name ("fr1_rpy_head", "rgbd_dataset_freiburg2_desk") or by
// the ground-truth header ("# file: 'rgbd_dataset_freiburg1_rpy.bag'").
std::optional<std::string> tum_camera_named_in(const std::string& text) {
  const std::string name = lower(text);
  for (const char digit : {'1', '2', '3'}) {
    const std::string long_name = std::string("freiburg") + digit;
    const std::string short_name = std::string("fr") + digit;
    if (name.find(long_name) != std::string::npos) return long_name;
    const auto at = name.find(short_name);
    // "fr1" must stand alone or be followed by a separator, not be part of a longer word.
    if (at != std::string::npos && (at == 0 || !std::isalpha(static_cast<unsigned char>(name[at - 1]))) &&
        (at + 3 == name.size() || !std::isdigit(static_cast<unsigned char>(name[at + 3])))) {
      return long_name;
    }
  }
  return std::nullopt;
}

std::string ground_truth_header(const fs::path& path) {
  std::ifstream in(path);
  std::string header;
  std::string line;
  for (int i = 0; i < 5 && std::getline(in, line); ++i) {
    if (!line.empty() && line[0] == '#') header += line + "\n";
  }
  return header;
}

// A warning when `stamps_s` (in file order) step backwards: the replay plays them in stamp order,
// which is not the order the file gives when a clock stepped back.
void warn_of_backward_stamps(const std::vector<double>& stamps_s, const fs::path& path, std::vector<std::string>& warnings) {
  std::size_t steps = 0;
  double largest_s = 0.0;
  for (std::size_t i = 1; i < stamps_s.size(); ++i) {
    if (stamps_s[i] >= stamps_s[i - 1]) continue;
    ++steps;
    largest_s = std::max(largest_s, stamps_s[i - 1] - stamps_s[i]);
  }
  if (steps == 0) return;
  char largest[32];
  std::snprintf(largest, sizeof largest, "%.6f", largest_s);
  warnings.push_back(path.string() + ": stamps go backwards " + std::to_string(steps) + " times (by up to " + largest +
                     " s); replayed in stamp order");
}

std::string read_can_log(const fs::path& path, std::vector<hal::CanFrame>& frames,
                         std::vector<std::string>& warnings) {
  std::ifstream in(path);
  if (!in) return "cannot open " + path.string();
  std::string line;
  int line_number = 0;
  int bad_lines = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (is_comment_or_blank(line)) continue;
    if (auto frame = hal::parse_candump_line(line)) {
      frames.push_back(*frame);
    } else if (++bad_lines <= 3) {
      warnings.push_back(path.string() + ":" + std::to_string(line_number) + ": not a candump -l frame, skipped");
    }
  }
  if (bad_lines > 3) {
    warnings.push_back(path.string() + ": " + std::to_string(bad_lines) + " malformed lines skipped in all");
  }
  std::vector<double> stamps_s;
  stamps_s.reserve(frames.size());
  for (const hal::CanFrame& frame : frames) stamps_s.push_back(static_cast<double>(frame.stamp_ns) * 1e-9);
  warn_of_backward_stamps(stamps_s, path, warnings);
  std::stable_sort(frames.begin(), frames.end(),
                   [](const hal::CanFrame& a, const hal::CanFrame& b) { return a.stamp_ns < b.stamp_ns; });
  return {};
}

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

std::optional<hal::Calibration> tum_calibration(const std::string& camera_name) {
  hal::Calibration calibration;
  calibration.depth_scale = 5000.0;
  auto& rgb = calibration.rgb;
  rgb.model = hal::CameraModel::kPinhole;
  rgb.width = 640;
  rgb.height = 480;
  // Published colour intrinsics of the TUM RGB-D benchmark cameras.
  if (camera_name == "freiburg1") {
    rgb.fx = 517.3; rgb.fy = 516.5; rgb.cx = 318.6; rgb.cy = 255.3;
    rgb.distortion = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
  } else if (camera_name == "freiburg2") {
    rgb.fx = 520.9; rgb.fy = 521.0; rgb.cx = 325.1; rgb.cy = 249.7;
    rgb.distortion = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
  } else if (camera_name == "freiburg3") {
    rgb.fx = 535.4; rgb.fy = 539.2; rgb.cx = 320.1; rgb.cy = 247.6;
    rgb.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  } else {
    return std::nullopt;
  }
  calibration.source = "TUM " + camera_name + " published calibration";
  return calibration;
}

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

std::string open_recording(const fs::path& root, Recording& recording) {
  recording = Recording{};
  recording.root = root;
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return root.string() + ": not a directory";

  if (fs::exists(root / "groundtruth.txt")) recording.ground_truth = root / "groundtruth.txt";

  // Calibration: the recording's own file first, then the TUM camera its name or ground truth names.
  if (fs::exists(root / "calibration.yaml")) {
    if (auto error = load_calibration_yaml(root / "calibration.yaml", recording.calibration); !error.empty()) {
      return error;
    }
  } else {
    auto camera = tum_camera_named_in(fs::weakly_canonical(root, ec).filename().string());
    if (!camera && recording.ground_truth) camera = tum_camera_named_in(ground_truth_header(*recording.ground_truth));
    if (!camera) {
      return root.string() +
             ": no calibration.yaml, and neither the folder name nor groundtruth.txt names a TUM camera "
             "(freiburg1/2/3); add a calibration.yaml (see README, 'Recording format')";
    }
    recording.calibration = *tum_calibration(*camera);
  }

  // Colour-depth pairs: associations.txt when present, otherwise nearest stamps within 0.02 s.
  if (fs::exists(root / "associations.txt")) {
    if (auto error = read_associations(root / "associations.txt", recording.frames); !error.empty()) return error;
  } else {
    std::vector<StampedFile> rgb;
    std::vector<StampedFile> depth;
    if (auto error = read_stamped_list(root / "rgb.txt", rgb); !error.empty()) return error;
    if (auto error = read_stamped_list(root / "depth.txt", depth); !error.empty()) return error;
    for (const auto& [i, j] : hal::associate_stamps(stamps_of(rgb), stamps_of(depth), kMaxAssociationGap_s)) {
      recording.frames.push_back({rgb[i].stamp_s, rgb[i].file, depth[j].stamp_s, depth[j].file, {}});
    }
    const std::size_t unmatched = rgb.size() - recording.frames.size();
    if (unmatched > 0) {
      recording.warnings.push_back((root / "rgb.txt").string() + ": " + std::to_string(unmatched) +
                                   " colour images have no depth image within 0.02 s and are not replayed");
    }
  }
  if (recording.frames.empty()) return root.string() + ": no associated colour and depth images";
  if (fs::exists(root / "associations.txt")) {
    std::vector<double> stamps_s;
    stamps_s.reserve(recording.frames.size());
    for (const FrameEntry& frame : recording.frames) stamps_s.push_back(frame.rgb_stamp_s);
    warn_of_backward_stamps(stamps_s, root / "associations.txt", recording.warnings);
  }
  std::stable_sort(recording.frames.begin(), recording.frames.end(),
                   [](const FrameEntry& a, const FrameEntry& b) { return a.rgb_stamp_s < b.rgb_stamp_s; });

  if (fs::exists(root / "ir.txt")) {
    std::vector<StampedFile> ir;
    if (auto error = read_stamped_list(root / "ir.txt", ir); !error.empty()) return error;
    std::vector<double> frame_stamps;
    frame_stamps.reserve(recording.frames.size());
    for (const auto& frame : recording.frames) frame_stamps.push_back(frame.depth_stamp_s);
    for (const auto& [i, j] : hal::associate_stamps(frame_stamps, stamps_of(ir), kMaxAssociationGap_s)) {
      recording.frames[i].ir_file = ir[j].file;
    }
  }
  if (fs::exists(root / "fisheye.txt")) {
    std::vector<StampedFile> fisheye;
    if (auto error = read_stamped_list(root / "fisheye.txt", fisheye); !error.empty()) return error;
    if (!recording.calibration.fisheye) {
      recording.warnings.push_back((root / "fisheye.txt").string() +
                                   ": no cameras.fisheye in the calibration; fisheye images are ignored");
    } else {
      for (auto& entry : fisheye) recording.fisheye.push_back({entry.stamp_s, std::move(entry.file)});
    }
  }
  if (fs::exists(root / "can.log")) {
    if (auto error = read_can_log(root / "can.log", recording.can_frames, recording.warnings); !error.empty()) {
      return error;
    }
  }
  return {};
}

}  // namespace rankslam::replay
