#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

namespace rankslam::hal {

/// Reads the whole of `path` into `bytes`, reusing its capacity, when it is a regular file of
/// at most `max_bytes`. Anything else (directory, FIFO, device, socket) is refused without
/// waiting: the file is opened non-blocking and checked with fstat before a byte is read.
/// Returns an empty string on success, otherwise a message naming the file and the cause.
[[nodiscard]] std::string read_regular_file(const std::filesystem::path& path, std::size_t max_bytes,
                                            std::vector<unsigned char>& bytes);
[[nodiscard]] std::string read_regular_file(const std::filesystem::path& path, std::size_t max_bytes,
                                            std::string& text);

}  // namespace rankslam::hal
