#include "rankslam/hal/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace rankslam::hal {

std::string write_file_atomically(const std::filesystem::path& path, std::span<const char> bytes) {
  const std::filesystem::path temp = path.string() + ".tmp." + std::to_string(::getpid());
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return "cannot create " + temp.string() + ": " + std::strerror(errno);
  }
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string error = "cannot write " + temp.string() + ": " + std::strerror(errno);
      ::close(fd);
      ::unlink(temp.c_str());
      return error;
    }
    written += static_cast<std::size_t>(n);
  }
  // fsync before rename: otherwise a power cut can leave a renamed but empty file.
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const std::string error = "cannot flush " + temp.string() + ": " + std::strerror(errno);
    ::unlink(temp.c_str());
    return error;
  }
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string error = "cannot rename " + temp.string() + " to " + path.string() + ": " +
                              std::strerror(errno);
    ::unlink(temp.c_str());
    return error;
  }
  // The rename is durable only once the directory is: a power cut could otherwise bring back
  // the previous file.
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  if (std::string error = sync_directory(dir); !error.empty()) {
    return "cannot flush the directory of " + path.string() + ": " + error;
  }
  return {};
}

std::string sync_directory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return std::strerror(errno);
  const int result = ::fsync(fd);
  const std::string error = result != 0 ? std::strerror(errno) : std::string();
  ::close(fd);
  return error;
}

std::string write_file_atomically(const std::filesystem::path& path, std::string_view text) {
  return write_file_atomically(path, std::span<const char>(text.data(), text.size()));
}

}  // namespace rankslam::hal
