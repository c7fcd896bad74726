#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <string_view>

namespace rankslam::hal {

/// Writes `bytes` to `path` so a reader never sees a half-written file: the data goes to a
/// temporary file in the same directory, is flushed to disk, then renamed over `path`.
/// Returns an empty string on success, otherwise a message naming the file and the cause.
[[nodiscard]] std::string write_file_atomically(const std::filesystem::path& path,
                                                std::span<const char> bytes);
[[nodiscard]] std::string write_file_atomically(const std::filesystem::path& path,
                                                std::string_view text);

}  // namespace rankslam::hal
