#include "robot_config.hpp"

#include "config_file.hpp"

#include "rankslam/hal/thread_priority.hpp"
#include "rankslam/replay/calibration_file.hpp"
#include "rankslam/yaml/strict_yaml.hpp"

#include <cstdint>
#include <limits>
#include <map>
#include <set>
#include <sstream>

namespace rankslam::app {
namespace {

// This loader's sections and their keys; `slam`, `geometry` and `wheel_odometry` are
// load_pipeline_config's (read_config_file knows them).
const std::map<std::string, std::set<std::string>> kKeys = {
    {"robot", {"name"}},
    {"camera", {"source", "replay_rate", "max_frames", "exit_after_end_s", "calibration", "mounting", "width", "height", "fps", "ir"}},
    {"wide_camera", {"device", "width", "height", "fps", "format"}},
    {"can", {"interface", "play_wheel_frames"}},
    {"output", {"pose_rate_hz", "heartbeat_rate_hz", "watchdog_timeout_s", "lost_after_failed_frames", "wheel_propagation", "dir",
                "max_trajectory_poses", "realtime_priority", "status_interval_s"}},
    {"map", {"file", "checkpoint_s"}},
};

// A string or boolean.
template <typename T>
std::string read(const YAML::Node& section, const std::string& where, const char* key, T& value) {
  const YAML::Node node = section[key];
  if (!node) return {};
  try {
    value = node.as<T>();
  } catch (const YAML::Exception&) {
    return where + "." + key + " is not a valid value" + yaml::at(node.Mark());
  }
  return {};
}

// A number, finite and within [min, max].
template <typename T>
std::string read_number(const YAML::Node& section, const std::string& where, const char* key, T min, T max, T& value) {
  const YAML::Node node = section[key];
  if (!node) return {};
  return yaml::read_number(node, where + "." + key, min, max, value);
}

// Any finite value: nav::validate checks the output's ranges.
constexpr double kAnyFinite = std::numeric_limits<double>::max();

}  // namespace

const std::set<std::string>& robot_config_sections() {
  static const std::set<std::string> sections = [] {
    std::set<std::string> names;
    for (const auto& [name, keys] : kKeys) names.insert(name);
    return names;
  }();
  return sections;
}

std::string load_robot_config(const std::filesystem::path& path, RobotConfig& config) {
  YAML::Node root;
  if (auto error = read_config_file(path, robot_config_sections(), root); !error.empty()) return error;
  const std::string file = path.string() + ": ";
  for (const auto& [name, keys] : kKeys) {
    if (!root[name]) continue;
    if (auto error = yaml::check_map(root[name], name, keys, "parameter"); !error.empty()) return file + error;
  }

  std::string error;
  const auto check = [&](std::string e) {
    if (error.empty() && !e.empty()) error = file + e;
  };
  const YAML::Node camera = root["camera"];
  if (!camera || !camera["source"]) return file + "camera.source is missing (replay:<recording dir> or openni2:[uri])";
  std::string source;
  check(read(camera, "camera", "source", source));
  if (!error.empty()) return error;
  if (source.rfind("replay:", 0) == 0) {
    config.camera_source = CameraSource::kReplay;
    std::filesystem::path dir = source.substr(7);
    if (dir.empty()) return file + "camera.source 'replay:' needs a recording directory";
    if (dir.is_relative()) dir = path.parent_path() / dir;
    config.camera_location = dir.lexically_normal().string();
  } else if (source.rfind("openni2:", 0) == 0) {
    config.camera_source = CameraSource::kOpenNI2;
    config.camera_location = source.substr(8);
  } else {
    return file + "camera.source '" + source + "' must start with replay: or openni2:";
  }
  check(read_number(camera, "camera", "replay_rate", 0.0, 100.0, config.replay_rate));
  check(read_number(camera, "camera", "max_frames", std::uint32_t{0}, std::numeric_limits<std::uint32_t>::max(),
                    config.max_frames));
  // Negative: until a signal; a million seconds (11 days) is as good as forever.
  check(read_number(camera, "camera", "exit_after_end_s", -1e6, 1e6, config.exit_after_end_s));
  std::string calibration;
  check(read(camera, "camera", "calibration", calibration));
  if (!calibration.empty()) {
    config.camera_calibration = calibration;
    if (config.camera_calibration.is_relative()) config.camera_calibration = path.parent_path() / config.camera_calibration;
  }
  if (const YAML::Node mounting = camera["mounting"]; mounting && error.empty()) {
    if (mounting.IsMap()) {
      Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
      if (auto e = replay::read_mounting(mounting, "camera.mounting", T_base_cam); !e.empty()) return file + e;
      config.camera_mounting = T_base_cam;
    } else if (mounting.IsScalar() && mounting.Scalar() == "identity") {
      config.camera_mounting = Eigen::Isometry3d::Identity();
    } else {
      return file + "camera.mounting must be identity or {translation: [x, y, z], rotation_xyzw: [x, y, z, w]}" +
             yaml::at(mounting.Mark());
    }
  }
  check(read_number(camera, "camera", "width", 1, 4096, config.camera_width));
  check(read_number(camera, "camera", "height", 1, 4096, config.camera_height));
  check(read_number(camera, "camera", "fps", 1, 240, config.camera_fps));
  check(read(camera, "camera", "ir", config.camera_ir));

  if (const YAML::Node wide = root["wide_camera"]; wide) {
    check(read(wide, "wide_camera", "device", config.wide_device));
    check(read_number(wide, "wide_camera", "width", 1, 4096, config.wide_width));
    check(read_number(wide, "wide_camera", "height", 1, 4096, config.wide_height));
    check(read_number(wide, "wide_camera", "fps", 0, 240, config.wide_fps));
    check(read(wide, "wide_camera", "format", config.wide_format));
    if (error.empty() && config.wide_format != "auto" && config.wide_format != "yuyv" && config.wide_format != "mjpeg") {
      error = file + "wide_camera.format must be auto, yuyv or mjpeg, not '" + config.wide_format + "'";
    }
  }

  const YAML::Node can = root["can"];
  if (can) {
    check(read(can, "can", "interface", config.can_interface));
    config.can_interface_given = static_cast<bool>(can["interface"]);
    check(read(can, "can", "play_wheel_frames", config.play_wheel_frames));
  }
  if (error.empty() && (config.can_interface.empty() || config.can_interface.size() >= 16)) {
    error = file + "can.interface must be a network interface name of 1 .. 15 characters";
  }

  const YAML::Node output = root["output"];
  if (output) {
    check(read_number(output, "output", "pose_rate_hz", -kAnyFinite, kAnyFinite, config.output.pose_rate_hz));
    check(read_number(output, "output", "heartbeat_rate_hz", -kAnyFinite, kAnyFinite, config.output.heartbeat_rate_hz));
    check(read_number(output, "output", "watchdog_timeout_s", -kAnyFinite, kAnyFinite, config.output.watchdog_timeout_s));
    check(read_number(output, "output", "lost_after_failed_frames", std::numeric_limits<int>::min(),
                      std::numeric_limits<int>::max(), config.output.lost_after_failed_frames));
    check(read(output, "output", "wheel_propagation", config.output.wheel_propagation));
    std::string dir;
    check(read(output, "output", "dir", dir));
    if (!dir.empty()) {
      config.output_dir = dir;
      if (config.output_dir.is_relative()) config.output_dir = path.parent_path() / config.output_dir;
    }
    check(read_number(output, "output", "max_trajectory_poses", std::uint32_t{1}, std::uint32_t{10'000'000},
                      config.max_trajectory_poses));
    check(read_number(output, "output", "realtime_priority", 0, hal::kMaxRealtimePriority, config.output_realtime_priority));
    // Up to a day; 0 turns the line off.
    check(read_number(output, "output", "status_interval_s", 0.0, 86400.0, config.status_interval_s));
  }
  const YAML::Node map = root["map"];
  if (map) {
    std::string file_name;
    check(read(map, "map", "file", file_name));
    if (!file_name.empty()) {
      config.map_file = file_name;
      if (config.map_file.is_relative()) config.map_file = path.parent_path() / config.map_file;
    }
    // Up to a day; 0 = only at the end.
    check(read_number(map, "map", "checkpoint_s", 0.0, 86400.0, config.checkpoint_s));
  }
  if (!error.empty()) return error;
  if (auto range = nav::validate(config.output); !range.empty()) return file + "output." + range;
  return {};
}

std::string describe_robot_config(const RobotConfig& config) {
  std::ostringstream text;
  text << "camera.source = "
       << (config.camera_source == CameraSource::kReplay ? "replay:" : "openni2:") << config.camera_location << "\n"
       << "camera.calibration = " << config.camera_calibration.string() << "  # openni2: empty = from the field of view\n"
       << "camera.mounting = " << (config.camera_mounting ? "given" : "from the calibration")
       << "  # T_base_cam, camera optical frame -> base\n"
       << "camera.mode = " << config.camera_width << "x" << config.camera_height << "@" << config.camera_fps
       << (config.camera_ir ? " + IR" : "") << "  # openni2 only\n"
       << "wide_camera.device = " << config.wide_device << "  # V4L2; empty = none (replay: the recording's wide-angle images)\n"
       << "wide_camera.mode = " << config.wide_width << "x" << config.wide_height << "@" << config.wide_fps << " "
       << config.wide_format << "\n"
       << "camera.replay_rate = " << config.replay_rate << "  # x recorded rate, 0 = lossless\n"
       << "camera.max_frames = " << config.max_frames << "  # 0 = all\n"
       << "camera.exit_after_end_s = " << config.exit_after_end_s << " s  # negative = until SIGINT/SIGTERM\n"
       << "can.interface = " << config.can_interface << "\n"
       << "can.play_wheel_frames = " << (config.play_wheel_frames ? "true" : "false") << "\n"
       << "output.pose_rate_hz = " << config.output.pose_rate_hz << " Hz\n"
       << "output.heartbeat_rate_hz = " << config.output.heartbeat_rate_hz << " Hz\n"
       << "output.watchdog_timeout_s = " << config.output.watchdog_timeout_s << " s\n"
       << "output.lost_after_failed_frames = " << config.output.lost_after_failed_frames << "\n"
       << "output.wheel_propagation = " << (config.output.wheel_propagation ? "true" : "false") << "\n"
       << "output.dir = " << config.output_dir.string() << "\n"
       << "output.max_trajectory_poses = " << config.max_trajectory_poses << "\n"
       << "output.realtime_priority = " << config.output_realtime_priority << "  # SCHED_FIFO, 0 = ordinary scheduling\n"
       << "output.status_interval_s = " << config.status_interval_s << " s  # status line on stderr, 0 = none\n"
       << "map.file = " << config.map_file.string() << "  # loaded at start when it exists, saved at checkpoints and at exit\n"
       << "map.checkpoint_s = " << config.checkpoint_s << " s  # map and outputs written this often, 0 = at exit only\n";
  return text.str();
}

}  // namespace rankslam::app
