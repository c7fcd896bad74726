#include "rankslam/hal/file_set.hpp"
#include "rankslam/hal/atomic_file.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <optional>
#include <system_error>

namespace rankslam::hal {
namespace {

namespace fs = std::filesystem;

constexpr std::string_view kLatest = "latest";
constexpr std::string_view kSetPrefix = "set-";
constexpr std::string_view kTempInfix = ".tmp.";
constexpr std::string_view kProbePrefix = ".rankslam-probe.";

std::optional<unsigned long> parse_number(std::string_view text) {
  unsigned long value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (text.empty() || error != std::errc() || end != text.data() + text.size()) return std::nullopt;
  return value;
}

struct SetName {
  unsigned long sequence = 0;
  pid_t pid = 0;
};

/// "set-<n>.<pid>", the name of a staged or published set.
std::optional<SetName> parse_set_name(std::string_view name) {
  if (!name.starts_with(kSetPrefix)) return std::nullopt;
  name.remove_prefix(kSetPrefix.size());
  const std::size_t dot = name.find('.');
  if (dot == std::string_view::npos) return std::nullopt;
  const auto sequence = parse_number(name.substr(0, dot));
  const auto pid = parse_number(name.substr(dot + 1));
  if (!sequence || !pid || *pid == 0) return std::nullopt;
  return SetName{*sequence, static_cast<pid_t>(*pid)};
}

struct TempName {
  std::string base;
  pid_t pid = 0;
};

/// "<base>.tmp.<pid>", the name of a link being replaced (and of hal::write_file_atomically's files).
std::optional<TempName> parse_temp_name(std::string_view name) {
  const std::size_t infix = name.rfind(kTempInfix);
  if (infix == std::string_view::npos || infix == 0) return std::nullopt;
  const auto pid = parse_number(name.substr(infix + kTempInfix.size()));
  if (!pid || *pid == 0) return std::nullopt;
  return TempName{std::string(name.substr(0, infix)), static_cast<pid_t>(*pid)};
}

std::string temp_suffix() { return std::string(kTempInfix) + std::to_string(::getpid()); }

// A pid equal to ours is a leftover of an earlier process: this one has made nothing yet.
bool is_alive(pid_t pid) { return pid != ::getpid() && (::kill(pid, 0) == 0 || errno == EPERM); }

std::string read_link(const fs::path& link) {
  std::array<char, 4096> buffer{};
  const ssize_t n = ::readlink(link.c_str(), buffer.data(), buffer.size());
  if (n <= 0 || static_cast<std::size_t>(n) >= buffer.size()) return {};
  return std::string(buffer.data(), static_cast<std::size_t>(n));
}

std::string errno_text() { return std::strerror(errno); }

/// The entries of `dir`; none when it cannot be read.
std::vector<fs::directory_entry> list_directory(const fs::path& dir) {
  std::vector<fs::directory_entry> entries;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    entries.push_back(*it);
  }
  return entries;
}

/// Creates `path` (which must not exist), writes `bytes` and fsyncs; empty or strerror.
std::string write_synced(const fs::path& path, std::span<const char> bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) return errno_text();
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string error = errno_text();
      ::close(fd);
      return error;
    }
    written += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const std::string error = errno_text();
    ::close(fd);
    return error;
  }
  if (::close(fd) != 0) return errno_text();
  return {};
}

/// Points `link` at `target` with one rename(2): readers see the old target or the new one.
std::string replace_symlink(const fs::path& link, const std::string& target) {
  const fs::path temp = link.string() + temp_suffix();
  ::unlink(temp.c_str());
  if (::symlink(target.c_str(), temp.c_str()) != 0) return "cannot create " + temp.string() + ": " + errno_text();
  if (::rename(temp.c_str(), link.c_str()) != 0) {
    const std::string error = "cannot replace " + link.string() + ": " + errno_text();
    ::unlink(temp.c_str());
    return error;
  }
  return {};
}

/// Whether `entry` (in `dir`, whose `latest` points at `published`) is a leftover of a FileSet
/// of a process no longer alive.
bool is_own_leftover(const fs::path& dir, const fs::directory_entry& entry, const std::string& published) {
  std::error_code ec;
  const std::string name = entry.path().filename().string();
  const fs::file_type type = entry.symlink_status(ec).type();
  if (const auto set = parse_set_name(name)) {
    return type == fs::file_type::directory && name != published && !is_alive(set->pid);
  }
  if (name.starts_with(kProbePrefix)) {
    const auto pid = parse_number(std::string_view(name).substr(kProbePrefix.size()));
    return pid && type == fs::file_type::regular && !is_alive(static_cast<pid_t>(*pid));
  }
  const auto temp = parse_temp_name(name);
  if (!temp || is_alive(temp->pid)) return false;
  const std::string own_link = std::string(kLatest) + "/" + temp->base;
  if (type == fs::file_type::symlink) {
    const std::string target = read_link(entry.path());
    return (temp->base == kLatest && parse_set_name(target)) || target == own_link;
  }
  // A file of the single-file writer, beside a name that is now one of our links.
  return type == fs::file_type::regular && read_link(dir / temp->base) == own_link;
}

/// Writes one byte into `dir` without leaving a name behind where the file system allows.
std::string probe_write(const fs::path& dir) {
  int fd = ::open(dir.c_str(), O_TMPFILE | O_WRONLY | O_CLOEXEC, 0600);
  fs::path named;
  if (fd < 0 && (errno == EOPNOTSUPP || errno == EISDIR || errno == EINVAL)) {
    named = dir / (std::string(kProbePrefix) + std::to_string(::getpid()));
    fd = ::open(named.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  }
  if (fd < 0) return errno_text();
  std::string error;
  while (::write(fd, "x", 1) != 1) {
    if (errno == EINTR) continue;
    error = errno_text();
    break;
  }
  ::close(fd);
  if (!named.empty()) ::unlink(named.c_str());
  return error;
}

}  // namespace

FileSet::FileSet(std::filesystem::path dir) : dir_(std::move(dir)) {}

FileSet::~FileSet() {
  if (!published_) abandon();
}

std::string FileSet::stage(std::string_view name, fs::path& path) {
  if (name.empty() || name.find('/') != std::string_view::npos || name == kLatest || parse_set_name(name) ||
      parse_temp_name(name)) {
    return fail("cannot write " + (dir_ / name).string() + ": not a name an output set may hold");
  }
  if (staging_.empty()) {
    unsigned long sequence = 0;
    for (const auto& entry : list_directory(dir_)) {
      if (const auto set = parse_set_name(entry.path().filename().string())) sequence = std::max(sequence, set->sequence);
    }
    for (;;) {
      ++sequence;
      const fs::path candidate = dir_ / (std::string(kSetPrefix) + std::to_string(sequence) + "." + std::to_string(::getpid()));
      if (::mkdir(candidate.c_str(), 0755) == 0) {
        staging_ = candidate;
        break;
      }
      if (errno != EEXIST) return fail("cannot create " + candidate.string() + ": " + errno_text());
    }
  }
  path = staging_ / name;
  names_.emplace_back(name);
  return {};
}

std::string FileSet::add(std::string_view name, std::span<const char> bytes) {
  return add_written(name, [bytes](const fs::path& path) { return write_synced(path, bytes); });
}

std::string FileSet::add(std::string_view name, std::string_view text) {
  return add(name, std::span<const char>(text.data(), text.size()));
}

std::string FileSet::add_written(std::string_view name,
                                 const std::function<std::string(const std::filesystem::path&)>& write) {
  if (failed_ || published_) return {};
  fs::path path;
  if (auto error = stage(name, path); !error.empty()) return error;
  if (auto error = write(path); !error.empty()) return fail("cannot write " + (dir_ / name).string() + ": " + error);
  return {};
}

std::string FileSet::publish() {
  if (failed_) return "nothing of this run was published: " + dir_.string() + " keeps the previous outputs";
  if (published_ || staging_.empty()) return {};
  if (auto error = sync_directory(staging_); !error.empty()) {
    return fail("cannot flush " + staging_.string() + ": " + error);
  }
  // The links first: before the swap they lead into the previous set, after it into this one.
  for (const std::string& name : names_) {
    const std::string target = std::string(kLatest) + "/" + name;
    if (read_link(dir_ / name) == target) continue;
    if (auto error = replace_symlink(dir_ / name, target); !error.empty()) return fail(error);
  }
  const std::string previous = read_link(dir_ / kLatest);
  if (auto error = replace_symlink(dir_ / kLatest, staging_.filename().string()); !error.empty()) return fail(error);
  published_ = true;
  const std::string flush_error = sync_directory(dir_);
  if (parse_set_name(previous) && previous != staging_.filename().string()) {
    std::error_code ec;
    fs::remove_all(dir_ / previous, ec);
  }
  if (!flush_error.empty()) return "cannot flush " + dir_.string() + ": " + flush_error;
  return {};
}

std::string FileSet::fail(std::string error) {
  failed_ = true;
  abandon();
  return error;
}

void FileSet::abandon() {
  if (staging_.empty()) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
  staging_.clear();
}

std::string prepare_output_directory(const std::filesystem::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  // The error_code overload: a symbolic-link loop must be this message, not an exception.
  if (std::error_code status_ec; !fs::is_directory(dir, status_ec)) {
    if (!ec) ec = status_ec;
    return "cannot create output directory " + dir.string() + ": " + (ec ? ec.message() : "not a directory");
  }
  const std::string published = read_link(dir / kLatest);
  for (const auto& entry : list_directory(dir)) {
    if (is_own_leftover(dir, entry, published)) fs::remove_all(entry.path(), ec);
  }
  if (auto error = probe_write(dir); !error.empty()) return "cannot write into output directory " + dir.string() + ": " + error;
  return {};
}

}  // namespace rankslam::hal
