#include "config_file.hpp"

#include <yaml-cpp/yaml.h>

#include <set>
#include <sstream>

namespace rankslam::app {

std::string load_slam_config(const std::filesystem::path& path, slam::SlamConfig& config) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::Exception& error) {
    return path.string() + ": " + error.what();
  }
  const YAML::Node section = root["slam"];
  if (!section) return {};
  if (!section.IsMap()) return path.string() + ": 'slam' must be a map of parameters";
  std::string error;
  std::set<std::string> known{"icp_mode"};
  if (const YAML::Node icp = section["icp_mode"]) {
    const auto parsed = icp.IsScalar() ? slam::parse_icp_mode(icp.Scalar()) : std::nullopt;
    if (!parsed) return path.string() + ": slam.icp_mode must be off, point_to_point or point_to_plane";
    config.icp_mode = *parsed;
  }
  config.visit_parameters([&](const char* name, auto& field, auto min, auto max, const char* /*unit*/,
                              const char* /*doc*/) {
    known.insert(name);
    if (!error.empty() || !section[name]) return;
    using Field = std::remove_reference_t<decltype(field)>;
    Field value{};
    try {
      value = section[name].template as<Field>();
    } catch (const YAML::Exception&) {
      error = path.string() + ": slam." + name + " is not a valid number";
      return;
    }
    if (value < static_cast<Field>(min) || value > static_cast<Field>(max)) {
      std::ostringstream message;
      message << path.string() << ": slam." << name << " = " << value << " is outside " << min << " .. " << max;
      error = message.str();
      return;
    }
    field = value;
  });
  if (!error.empty()) return error;
  for (const auto& entry : section) {
    const auto key = entry.first.as<std::string>();
    if (!known.contains(key)) return path.string() + ": slam." + key + " is not a known parameter";
  }
  if (config.min_depth_m >= config.max_depth_m) return path.string() + ": slam.min_depth_m must be below slam.max_depth_m";
  return {};
}

std::string describe_slam_config(slam::SlamConfig config) {
  std::ostringstream text;
  text << "slam.mode = " << slam::to_string(config.mode) << "\n";
  text << "slam.icp_mode = " << slam::to_string(config.icp_mode) << "  # ICP refinement after the feature registration\n";
  config.visit_parameters([&](const char* name, auto& field, auto, auto, const char* unit, const char* doc) {
    text << "slam." << name << " = " << field << (unit[0] != '\0' ? " " : "") << unit << "  # " << doc << "\n";
  });
  return text.str();
}

std::string slam_config_json(slam::SlamConfig config) {
  std::ostringstream text;
  text << "\"mode\": \"" << slam::to_string(config.mode) << "\"";
  text << ", \"icp_mode\": \"" << slam::to_string(config.icp_mode) << "\"";
  config.visit_parameters([&](const char* name, auto& field, auto, auto, const char*, const char*) {
    text << ", \"" << name << "\": " << field;
  });
  return text.str();
}

}  // namespace rankslam::app
