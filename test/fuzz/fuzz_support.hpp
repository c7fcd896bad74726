#pragma once
// Helpers shared by the fuzz targets: a fuzz input as a file, since the readers under test take
// paths, and a failed property as a crash libFuzzer reports with its input.

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace rankslam::fuzz {

/// A directory of this process's own under the temp directory (kept for the whole run, since
/// creating one per input would dominate the time of each execution).
inline const std::filesystem::path& scratch_dir() {
  static const std::filesystem::path dir = [] {
    auto path = std::filesystem::temp_directory_path() / ("rankslam_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(path);
    return path;
  }();
  return dir;
}

inline void write_file(const std::filesystem::path& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// Aborts (a libFuzzer crash with the input saved) when a property does not hold.
inline void require(bool holds, const char* what) {
  if (!holds) {
    std::fprintf(stderr, "property violated: %s\n", what);
    std::abort();
  }
}

}  // namespace rankslam::fuzz
