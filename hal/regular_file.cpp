#include "rankslam/hal/regular_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <system_error>

namespace rankslam::hal {
namespace {

std::string kind_of(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

std::string mebibytes(std::size_t bytes) { return std::to_string(bytes >> 20U) + " MiB"; }

std::string check_stat(const std::filesystem::path& path, const struct stat& info, std::size_t max_bytes) {
  if (!S_ISREG(info.st_mode)) return path.string() + ": " + kind_of(info.st_mode) + ", not a regular file";
  if (static_cast<std::uintmax_t>(info.st_size) > max_bytes) {
    return path.string() + ": " + std::to_string(info.st_size) + " bytes, more than the " + mebibytes(max_bytes) +
           " such a file may have";
  }
  return {};
}

class FileDescriptor {
 public:
  explicit FileDescriptor(int fd) : fd_(fd) {}
  ~FileDescriptor() {
    if (fd_ >= 0) ::close(fd_);
  }
  FileDescriptor(const FileDescriptor&) = delete;
  FileDescriptor& operator=(const FileDescriptor&) = delete;
  [[nodiscard]] int get() const { return fd_; }

 private:
  int fd_;
};

template <typename Bytes>
std::string read_into(const std::filesystem::path& path, std::size_t max_bytes, Bytes& bytes) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, forever.
  const FileDescriptor file(::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC));
  if (file.get() < 0) return "cannot open " + path.string() + ": " + std::strerror(errno);
  struct stat info {};
  if (::fstat(file.get(), &info) != 0) return "cannot read " + path.string() + ": " + std::strerror(errno);
  if (auto error = check_stat(path, info, max_bytes); !error.empty()) return error;
  const int flags = ::fcntl(file.get(), F_GETFL);
  if (flags < 0 || ::fcntl(file.get(), F_SETFL, flags & ~O_NONBLOCK) != 0) {
    return "cannot read " + path.string() + ": " + std::strerror(errno);
  }
  // The size fstat gave: a file growing meanwhile is read as it was, one shrinking as it is.
  bytes.resize(static_cast<std::size_t>(info.st_size));
  std::size_t filled = 0;
  while (filled < bytes.size()) {
    const ssize_t n = ::read(file.get(), bytes.data() + filled, bytes.size() - filled);
    if (n < 0) {
      if (errno == EINTR) continue;
      return "cannot read " + path.string() + ": " + std::strerror(errno);
    }
    if (n == 0) break;
    filled += static_cast<std::size_t>(n);
  }
  bytes.resize(filled);
  return {};
}

}  // namespace

std::string read_regular_file(const std::filesystem::path& path, std::size_t max_bytes,
                              std::vector<unsigned char>& bytes) {
  return read_into(path, max_bytes, bytes);
}

std::string read_regular_file(const std::filesystem::path& path, std::size_t max_bytes, std::string& text) {
  return read_into(path, max_bytes, text);
}

std::string check_regular_file(const std::filesystem::path& path, std::size_t max_bytes) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return "cannot open " + path.string() + ": " + std::strerror(errno);
  return check_stat(path, info, max_bytes);
}

bool path_exists(const std::filesystem::path& path, std::string& error) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory) {
    error = path.string() + ": " + ec.message();
    return false;
  }
  return std::filesystem::exists(status);
}

}  // namespace rankslam::hal
