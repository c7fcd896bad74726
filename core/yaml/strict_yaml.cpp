#include "rankslam/yaml/strict_yaml.hpp"

#include <system_error>

namespace rankslam::yaml {
namespace {

// Far beyond any file of ours (four levels, a few hundred values); they bound the walk below,
// which aliases could otherwise make exponential.
constexpr int kMaxDepth = 64;
constexpr int kMaxValues = 100'000;

std::string at_line(const YAML::Mark& mark) {
  return "line " + std::to_string(mark.line + 1) + ", column " + std::to_string(mark.column + 1);
}

std::string check_keys(const YAML::Node& node, const std::string& key_path, int depth, int& values) {
  if (++values > kMaxValues) return "more than " + std::to_string(kMaxValues) + " values (aliases expanded)";
  if (depth > kMaxDepth) {
    return "nested too deep (more than " + std::to_string(kMaxDepth) + " levels) at " + at_line(node.Mark());
  }
  if (node.IsMap()) {
    std::set<std::string> seen;
    for (const auto& entry : node) {
      if (!entry.first.IsScalar()) {
        return (key_path.empty() ? std::string("the top level") : key_path) + ": the key at " + at_line(entry.first.Mark()) +
               " is not a plain name";
      }
      const std::string& name = entry.first.Scalar();
      const std::string path = key_path.empty() ? name : key_path + "." + name;
      if (!seen.insert(name).second) return path + " is given twice (again at " + at_line(entry.first.Mark()) + ")";
      if (auto error = check_keys(entry.second, path, depth + 1, values); !error.empty()) return error;
    }
  } else if (node.IsSequence()) {
    for (std::size_t i = 0; i < node.size(); ++i) {
      if (auto error = check_keys(node[i], key_path + "[" + std::to_string(i) + "]", depth + 1, values); !error.empty()) {
        return error;
      }
    }
  }
  return {};
}

}  // namespace

std::string load_file(const std::filesystem::path& path, YAML::Node& root) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) return "cannot be opened (no such file)";
  // A FIFO or device would block or never end; a directory parses as an empty document.
  if (!std::filesystem::is_regular_file(status)) return "not a regular file";
  try {
    root = YAML::LoadFile(path.string());
  } catch (const YAML::BadFile&) {
    return "cannot be opened";
  } catch (const YAML::ParserException& error) {
    // yaml-cpp's depth guard throws DeepRecursion (not exported) with the message "bad file".
    if (error.msg == YAML::ErrorMsg::BAD_FILE) {
      return "not valid YAML (nested too deep) at " + at_line(error.mark);
    }
    return "not valid YAML: " + error.msg + " at " + at_line(error.mark);
  } catch (const YAML::Exception& error) {
    return "not valid YAML: " + error.msg + (error.mark.is_null() ? "" : " at " + at_line(error.mark));
  }
  int values = 0;
  return check_keys(root, "", 0, values);
}

std::string check_map(const YAML::Node& node, const std::string& key_path, const std::set<std::string>& known,
                      const std::string& noun) {
  if (!node.IsMap()) {
    return (key_path.empty() ? "expected a map at the top level" : "'" + key_path + "' must be a map") + at(node.Mark());
  }
  for (const auto& entry : node) {
    const std::string& name = entry.first.Scalar();
    if (known.contains(name)) continue;
    return (key_path.empty() ? "'" + name + "'" : key_path + "." + name) + " is not a known " + noun +
           at(entry.first.Mark());
  }
  return {};
}

}  // namespace rankslam::yaml
