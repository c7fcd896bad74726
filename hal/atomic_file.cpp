#include "rankslam/hal/atomic_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace rankslam::hal {
namespace {

/// Writes all of `bytes` to `fd` and fsyncs it: empty, or strerror's text. Leaves `fd` open.
std::string write_all_and_flush(int fd, std::span<const char> bytes) {
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      return std::strerror(errno);
    }
    written += static_cast<std::size_t>(n);
  }
  // fsync before the file gets its name: otherwise a power cut can leave a named but empty file.
  if (::fsync(fd) != 0) return std::strerror(errno);
  return {};
}

/// An unnamed file (O_TMPFILE) in `dir`, or -1 where the kernel or file system has none or /proc
/// (through which it is given a name) is not mounted.
int open_unnamed(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0644);
  if (fd < 0) return -1;
  const std::string link = "/proc/self/fd/" + std::to_string(fd);
  if (::access(link.c_str(), F_OK) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

}  // namespace

std::string write_file_atomically(const std::filesystem::path& path, std::span<const char> bytes) {
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : std::filesystem::path(".");
  const std::filesystem::path temp = path.string() + ".tmp." + std::to_string(::getpid());
  // Where it can, the data goes to an unnamed file that is linked as `temp` only once complete
  // and flushed: a process killed while writing leaves nothing behind.
  int fd = open_unnamed(dir);
  const bool unnamed = fd >= 0;
  if (!unnamed) fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    return "cannot create " + temp.string() + ": " + std::strerror(errno);
  }
  if (std::string error = write_all_and_flush(fd, bytes); !error.empty()) {
    ::close(fd);
    if (!unnamed) ::unlink(temp.c_str());
    return "cannot write " + temp.string() + ": " + error;
  }
  if (unnamed) {
    const std::string link = "/proc/self/fd/" + std::to_string(fd);
    ::unlink(temp.c_str());  // this process's own leftover of an earlier failed write
    if (::linkat(AT_FDCWD, link.c_str(), AT_FDCWD, temp.c_str(), AT_SYMLINK_FOLLOW) != 0) {
      const std::string error = "cannot link " + temp.string() + ": " + std::strerror(errno);
      ::close(fd);
      return error;
    }
  }
  if (::close(fd) != 0) {
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
