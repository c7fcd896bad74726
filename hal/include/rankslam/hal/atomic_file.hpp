#pragma once

#include <filesystem>
#include <span>
#include <string>
#include <string_view>

namespace rankslam::hal {

/// Writes `bytes` to `path` so a reader never sees a half-written file: the data goes to a
/// temporary file in the same directory, is flushed to disk, then renamed over `path`, and the
/// directory is flushed. Where the file system has O_TMPFILE, the temporary file has no name
/// until it is complete, so a process killed while writing leaves nothing half-written.
/// Returns an empty string on success, otherwise a message naming the file and the cause.
[[nodiscard]] std::string write_file_atomically(const std::filesystem::path& path,
                                                std::span<const char> bytes);
[[nodiscard]] std::string write_file_atomically(const std::filesystem::path& path,
                                                std::string_view text);

/// fsync(2) of a directory, making the renames and creations in it durable: empty on success,
/// else strerror's text.
[[nodiscard]] std::string sync_directory(const std::filesystem::path& dir);

}  // namespace rankslam::hal
