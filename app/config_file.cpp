#include "config_file.hpp"

#include "commands.hpp"
#include "exit_codes.hpp"

#include "rankslam/eval/json_writer.hpp"
#include "rankslam/hal/file_set.hpp"
#include "rankslam/yaml/strict_yaml.hpp"

#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <string_view>

namespace rankslam::app {

namespace {

// The sections the loaders here read; any other must be read by the caller's own loader.
const std::set<std::string> kPipelineSections = {"slam", "geometry", "wheel_odometry"};

// Reads the numeric parameters a config struct declares through visit_parameters from one YAML
// section; every key must be one of them.
template <typename Config>
std::string load_section(const std::filesystem::path& path, const YAML::Node& section, const std::string& section_name,
                         Config& config) {
  std::set<std::string> known;
  config.visit_parameters([&](auto name, auto&, auto, auto, auto, auto) { known.insert(name); });
  if (auto error = yaml::check_map(section, section_name, known, "parameter"); !error.empty()) {
    return path.string() + ": " + error;
  }
  std::string error;
  config.visit_parameters([&](auto name_arg, auto& field, auto min, auto max, auto /*unit*/, auto /*doc*/) {
    const std::string name(name_arg);
    if (!error.empty() || !section[name]) return;
    using Field = std::remove_reference_t<decltype(field)>;
    error = yaml::read_number(section[name], section_name + "." + name, static_cast<Field>(min),
                              static_cast<Field>(max), field);
  });
  if (!error.empty()) return path.string() + ": " + error;
  return {};
}

// The whole file, read strictly; a map of sections, or nothing (an empty file: every default).
std::string read_yaml(const std::filesystem::path& path, YAML::Node& root) {
  if (auto error = yaml::load_file(path, root); !error.empty()) return path.string() + ": " + error;
  if (!root.IsNull() && !root.IsMap()) return path.string() + ": expected a map of sections";
  return {};
}

}  // namespace

std::string read_config_file(const std::filesystem::path& path, const std::set<std::string>& other_sections,
                             YAML::Node& root) {
  if (auto error = read_yaml(path, root); !error.empty()) return error;
  if (root.IsNull()) return {};
  std::set<std::string> known = other_sections;
  known.insert(kPipelineSections.begin(), kPipelineSections.end());
  if (auto error = yaml::check_map(root, "", known, "section"); !error.empty()) {
    std::string names;
    for (const auto& name : known) names += (names.empty() ? "" : ", ") + name;
    return path.string() + ": " + error + " (sections: " + names + ")";
  }
  return {};
}

std::string load_slam_config(const std::filesystem::path& path, slam::SlamConfig& config) {
  YAML::Node root;
  if (auto error = read_yaml(path, root); !error.empty()) return error;
  if (const YAML::Node geometry = root["geometry"]) {
    if (auto error = load_section(path, geometry, "geometry", config.geometry); !error.empty()) return error;
  }
  const YAML::Node section = root["slam"];
  if (!section) return {};
  if (auto error = load_section(path, section, "slam", config); !error.empty()) return error;
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
    text << ", \"" << name << "\": " << eval::json_number(field);
  });
  config.geometry.visit_parameters([&](auto name, auto& field, auto, auto, auto, auto) {
    text << ", \"geometry." << name << "\": " << eval::json_number(field);
  });
  return text.str();
}

std::string load_wheel_config(const std::filesystem::path& path, nav::WheelOdometryConfig& config) {
  YAML::Node root;
  if (auto error = read_yaml(path, root); !error.empty()) return error;
  const YAML::Node section = root["wheel_odometry"];
  if (!section) return {};
  return load_section(path, section, "wheel_odometry", config);
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
                         slam::SlamConfig& slam_config, nav::WheelOdometryConfig& wheel_config,
                         const std::set<std::string>& other_sections) {
  if (!path.empty()) {
    YAML::Node root;
    if (auto error = read_config_file(path, other_sections, root); !error.empty()) {
      std::cerr << "error: " << error << "\n";
      return kExitInput;
    }
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

int load_vocabulary(const std::filesystem::path& path, std::optional<wide::Vocabulary>& vocabulary) {
  if (path.empty()) return kExitOk;
  try {
    vocabulary.emplace(wide::Vocabulary::load(path.string()));
  } catch (const std::exception& e) {
    std::cerr << "error: " << e.what() << "\n";
    return kExitInput;
  }
  return kExitOk;
}

int make_output_directory(const std::filesystem::path& dir) {
  if (auto error = hal::prepare_output_directory(dir); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitOutput;
  }
  return kExitOk;
}

}  // namespace rankslam::app
