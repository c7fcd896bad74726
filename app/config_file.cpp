#include "config_file.hpp"

#include "commands.hpp"
#include "exit_codes.hpp"

#include <yaml-cpp/yaml.h>

#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <string_view>

namespace rankslam::app {

namespace {

// Reads the numeric parameters a config struct declares through visit_parameters from one YAML
// section; every key must be one of them or in `named` (handled by the caller).
template <typename Config>
std::string load_section(const std::filesystem::path& path, const YAML::Node& section, const char* section_name,
                         std::set<std::string> known, Config& config) {
  std::string error;
  config.visit_parameters([&](auto name_arg, auto& field, auto min, auto max, auto /*unit*/, auto /*doc*/) {
    const std::string name(name_arg);
    known.insert(name);
    if (!error.empty() || !section[name]) return;
    using Field = std::remove_reference_t<decltype(field)>;
    Field value{};
    try {
      value = section[name].template as<Field>();
    } catch (const YAML::Exception&) {
      error = path.string() + ": " + section_name + "." + name + " is not a valid number";
      return;
    }
    if (value < static_cast<Field>(min) || value > static_cast<Field>(max)) {
      std::ostringstream message;
      message << path.string() << ": " << section_name << "." << name << " = " << value << " is outside " << min
              << " .. " << max;
      error = message.str();
      return;
    }
    field = value;
  });
  if (!error.empty()) return error;
  for (const auto& entry : section) {
    const auto key = entry.first.as<std::string>();
    if (!known.contains(key)) return path.string() + ": " + section_name + "." + key + " is not a known parameter";
  }
  return {};
}

// The whole file, or why it cannot be read (naming the file).
std::string read_yaml(const std::filesystem::path& path, YAML::Node& root) {
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::Exception& error) {
    return path.string() + ": " + error.what();
  }
  return {};
}

}  // namespace

std::string load_slam_config(const std::filesystem::path& path, slam::SlamConfig& config) {
  YAML::Node root;
  if (auto error = read_yaml(path, root); !error.empty()) return error;
  if (const YAML::Node geometry = root["geometry"]) {
    if (!geometry.IsMap()) return path.string() + ": 'geometry' must be a map of parameters";
    if (auto error = load_section(path, geometry, "geometry", {}, config.geometry); !error.empty()) return error;
  }
  const YAML::Node section = root["slam"];
  if (!section) return {};
  if (!section.IsMap()) return path.string() + ": 'slam' must be a map of parameters";
  if (auto error = load_section(path, section, "slam", {}, config); !error.empty()) return error;
  if (config.min_depth_m >= config.max_depth_m) return path.string() + ": slam.min_depth_m must be below slam.max_depth_m";
  return {};
}

std::string describe_slam_config(slam::SlamConfig config) {
  std::ostringstream text;
  text << "slam.mode = " << slam::to_string(config.mode) << "\n";
  config.visit_parameters([&](const char* name, auto& field, auto, auto, const char* unit, const char* doc) {
    text << "slam." << name << " = " << field << (unit[0] != '\0' ? " " : "") << unit << "  # " << doc << "\n";
  });
  config.geometry.visit_parameters([&](auto name, auto& field, auto, auto, auto unit, auto doc) {
    const std::string_view unit_text(unit);
    text << "geometry." << name << " = " << field << (unit_text.empty() ? "" : " ") << unit_text << "  # " << doc
         << "\n";
  });
  return text.str();
}

std::string slam_config_json(slam::SlamConfig config) {
  std::ostringstream text;
  text << "\"mode\": \"" << slam::to_string(config.mode) << "\"";
  config.visit_parameters([&](const char* name, auto& field, auto, auto, const char*, const char*) {
    text << ", \"" << name << "\": " << field;
  });
  config.geometry.visit_parameters([&](auto name, auto& field, auto, auto, auto, auto) {
    text << ", \"geometry." << name << "\": " << field;
  });
  return text.str();
}

std::string load_wheel_config(const std::filesystem::path& path, nav::WheelOdometryConfig& config) {
  YAML::Node root;
  if (auto error = read_yaml(path, root); !error.empty()) return error;
  const YAML::Node section = root["wheel_odometry"];
  if (!section) return {};
  if (!section.IsMap()) return path.string() + ": 'wheel_odometry' must be a map of parameters";
  return load_section(path, section, "wheel_odometry", {}, config);
}

std::string describe_wheel_config(nav::WheelOdometryConfig config) {
  std::ostringstream text;
  config.visit_parameters([&](const char* name, auto& field, auto, auto, const char* unit, const char* doc) {
    text << "wheel_odometry." << name << " = " << field << (unit[0] != '\0' ? " " : "") << unit << "  # " << doc
         << "\n";
  });
  return text.str();
}

int load_pipeline_config(const std::filesystem::path& path, const std::string& mode_name,
                         slam::SlamConfig& slam_config, nav::WheelOdometryConfig& wheel_config) {
  if (!path.empty()) {
    if (auto error = load_slam_config(path, slam_config); !error.empty()) {
      std::cerr << "error: " << error << "\n";
      return kExitInput;
    }
    if (auto error = load_wheel_config(path, wheel_config); !error.empty()) {
      std::cerr << "error: " << error << "\n";
      return kExitInput;
    }
  }
  slam_config.mode = kDefaultMode;
  if (!mode_name.empty()) {
    const auto mode = slam::parse_mode(mode_name);
    if (!mode) {
      std::cerr << "error: unknown mode '" << mode_name << "' (baseline, photometric, geometric, fused)\n";
      return kExitUsage;
    }
    slam_config.mode = *mode;
  }
  return kExitOk;
}

int make_output_directory(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  // The error_code overload: a symbolic-link loop must be this message, not an exception.
  if (std::error_code status_ec; !std::filesystem::is_directory(dir, status_ec)) {
    if (!ec) ec = status_ec;
    std::cerr << "error: cannot create output directory " << dir << ": " << ec.message() << "\n";
    return kExitOutput;
  }
  return kExitOk;
}

}  // namespace rankslam::app
