#pragma once
// Running the rankslam executable from the CLI tests (RANKSLAM_EXE is set per test target).

#include <sys/wait.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace cli_test {

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

/// Runs a shell command line; its exit code, or -1 when a signal ended it.
inline CommandResult run_shell(const std::string& command_line) {
  const std::string command = command_line + " 2>&1";
  CommandResult result;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer{};
  while (std::fgets(buffer.data(), buffer.size(), pipe) != nullptr) result.output += buffer.data();
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

/// Runs rankslam with `arguments`.
inline CommandResult run(const std::string& arguments) {
  // Appended, not `std::string(RANKSLAM_EXE) + " " + arguments`: GCC 12 reports a false
  // -Warray-bounds in that temporary's move at -O2.
  std::string command = RANKSLAM_EXE;
  command += ' ';
  command += arguments;
  return run_shell(command);
}

inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// An empty path of this name in the temporary directory (an earlier run's removed).
inline std::filesystem::path fresh_dir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / name;
  std::filesystem::remove_all(dir);
  return dir;
}

// A number in report.json; NaN when the key is absent or null.
inline double report_number(const std::string& report, const std::string& key) {
  const std::string needle = "\"" + key + "\": ";
  const auto at = report.find(needle);
  if (at == std::string::npos) return std::nan("");
  const char* start = report.c_str() + at + needle.size();
  char* end = nullptr;
  const double value = std::strtod(start, &end);
  return end == start ? std::nan("") : value;
}

}  // namespace cli_test
