#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace rankslam::hal {

/// Largest list file read whole (associations.txt, rgb.txt, depth.txt, ir.txt, fisheye.txt): a
/// line per frame of ~100 bytes, so 64 MiB holds days of 30 Hz frames.
inline constexpr std::size_t kMaxListFileBytes = std::size_t{64} << 20U;
/// Largest trajectory read whole (groundtruth.txt, an estimate): ~90 bytes per pose, so
/// 256 MiB holds eight hours at 100 Hz.
inline constexpr std::size_t kMaxTrajectoryFileBytes = std::size_t{256} << 20U;
/// Largest can.log read whole: ~45 bytes per frame, so 256 MiB holds a day of frames at 60 Hz.
inline constexpr std::size_t kMaxCanLogBytes = std::size_t{256} << 20U;

/// Reads the whole of `path` into `bytes`, reusing its capacity, when it is a regular file of
/// at most `max_bytes`. Anything else (directory, FIFO, device, socket) is refused without
/// waiting: the file is opened non-blocking and checked with fstat before a byte is read.
/// Returns an empty string on success, otherwise a message naming the file and the cause.
[[nodiscard]] std::string read_regular_file(const std::filesystem::path& path, std::size_t max_bytes,
                                            std::vector<unsigned char>& bytes);
[[nodiscard]] std::string read_regular_file(const std::filesystem::path& path, std::size_t max_bytes,
                                            std::string& text);

/// Checks, without opening it, that `path` is a regular file of at most `max_bytes`, for files
/// another library opens by name. Empty string when it is, otherwise why not, naming the file.
[[nodiscard]] std::string check_regular_file(const std::filesystem::path& path, std::size_t max_bytes);

/// Whether `path` names something (a dangling symbolic link names nothing). `error` is set,
/// naming the file, when that cannot be told (a symbolic-link loop, no permission); never throws.
[[nodiscard]] bool path_exists(const std::filesystem::path& path, std::string& error);

}  // namespace rankslam::hal
