#pragma once

#include <filesystem>
#include <functional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace rankslam::hal {

/// Output files that a reader sees all from one run or all from the previous one, never mixed,
/// whatever stops the process (kill -9, power cut, full disk).
///
/// Layout of `dir`: the files are staged, each fsynced, in a fresh directory `set-<n>.<pid>`;
/// publish() points the symlink `latest` at it with one rename(2). Each `<name>` is a symlink to
/// `latest/<name>`, so the documented paths resolve into one set at every moment. A set that is
/// never published leaves the previous one in place; its directory is removed by the destructor
/// or, after a kill, by the next prepare_output_directory().
class FileSet {
 public:
  /// Writes nothing until the first add().
  explicit FileSet(std::filesystem::path dir);
  /// Removes the staged directory of a set that was not published.
  ~FileSet();
  FileSet(const FileSet&) = delete;
  FileSet& operator=(const FileSet&) = delete;

  /// Writes `bytes` as `name` into the staged set and fsyncs it. Empty on success, else a message
  /// naming `<dir>/<name>`; after a failure the set is abandoned and later calls do nothing.
  [[nodiscard]] std::string add(std::string_view name, std::span<const char> bytes);
  [[nodiscard]] std::string add(std::string_view name, std::string_view text);
  /// As add(), for a writer that takes a path: `write(path)` writes and fsyncs the file there and
  /// returns an empty string or its error.
  [[nodiscard]] std::string add_written(std::string_view name,
                                        const std::function<std::string(const std::filesystem::path&)>& write);

  /// Makes the staged set the published one and removes the previous set. Empty on success, else
  /// a message; the previous set then stays published and the staged one is removed.
  [[nodiscard]] std::string publish();

 private:
  [[nodiscard]] std::string stage(std::string_view name, std::filesystem::path& path);
  [[nodiscard]] std::string fail(std::string error);
  void abandon();

  std::filesystem::path dir_;
  std::filesystem::path staging_;  ///< empty until the first add()
  std::vector<std::string> names_;
  bool failed_ = false;
  bool published_ = false;
};

/// Creates `dir` if needed, removes what FileSets of processes no longer alive left there (staged
/// sets, superseded sets, temporary links; nothing else) and checks that a file can be written
/// there. Empty on success, else a message naming `dir` and the cause.
[[nodiscard]] std::string prepare_output_directory(const std::filesystem::path& dir);

}  // namespace rankslam::hal
