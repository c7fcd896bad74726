#include "rankslam/hal/file_set.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

namespace rankslam::hal {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// Names in `dir`, without following links.
std::set<std::string> entries(const fs::path& dir) {
  std::set<std::string> names;
  for (const auto& entry : fs::directory_iterator(dir)) names.insert(entry.path().filename().string());
  return names;
}

/// The pid of a process that has exited and been reaped.
pid_t dead_pid() {
  const pid_t pid = ::fork();
  if (pid == 0) ::_exit(0);
  ::waitpid(pid, nullptr, 0);
  return pid;
}

void publish_set(const fs::path& dir, const std::string& a, const std::string& b) {
  FileSet set(dir);
  ASSERT_EQ(set.add("a.txt", std::string_view(a)), "");
  ASSERT_EQ(set.add_written("b.txt", [&](const fs::path& path) {
    std::ofstream(path) << b;
    return std::string();
  }), "");
  ASSERT_EQ(set.publish(), "");
}

TEST(FileSet, PublishesTheWholeSetAndRemovesThePreviousOne) {
  const fs::path dir = fresh_dir("rankslam_file_set_publish");
  publish_set(dir, "first a", "first b");
  EXPECT_EQ(slurp(dir / "a.txt"), "first a");
  EXPECT_EQ(slurp(dir / "b.txt"), "first b");
  publish_set(dir, "second a", "second b");
  EXPECT_EQ(slurp(dir / "a.txt"), "second a");
  EXPECT_EQ(slurp(dir / "b.txt"), "second b");
  EXPECT_TRUE(fs::is_symlink(dir / "a.txt"));
  EXPECT_EQ(fs::read_symlink(dir / "a.txt"), "latest/a.txt");
  // The documented names, the link to the set and the one set: nothing else, no temporary.
  const std::set<std::string> names = entries(dir);
  ASSERT_EQ(names.size(), 4U) << ::testing::PrintToString(names);
  const std::string set_name = fs::read_symlink(dir / "latest").string();
  EXPECT_EQ(names, (std::set<std::string>{"a.txt", "b.txt", "latest", set_name}));
  EXPECT_EQ(entries(dir / set_name), (std::set<std::string>{"a.txt", "b.txt"}));
  fs::remove_all(dir);
}

TEST(FileSet, ASetNeverPublishedLeavesThePreviousOneAndNoStagingDirectory) {
  const fs::path dir = fresh_dir("rankslam_file_set_abandon");
  publish_set(dir, "first a", "first b");
  const std::set<std::string> before = entries(dir);
  {
    FileSet set(dir);
    ASSERT_EQ(set.add("a.txt", std::string_view("second a")), "");
    EXPECT_EQ(entries(dir).size(), before.size() + 1);  // the staged set
  }
  EXPECT_EQ(entries(dir), before);
  EXPECT_EQ(slurp(dir / "a.txt"), "first a");
  EXPECT_EQ(slurp(dir / "b.txt"), "first b");
  fs::remove_all(dir);
}

TEST(FileSet, AWriteThatFailsKeepsThePreviousSetAndNamesTheFile) {
  const fs::path dir = fresh_dir("rankslam_file_set_full");
  publish_set(dir, "first a", "first b");
  const std::set<std::string> before = entries(dir);
  // A full disk, as the file-size limit gives it unprivileged: write(2) fails with EFBIG.
  rlimit old_limit{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  rlimit limit = old_limit;
  limit.rlim_cur = 1024;
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
  std::string add_error;
  std::string publish_error;
  {
    FileSet set(dir);
    const std::string small = "small";
    const std::string large(4096, 'x');
    add_error = set.add("a.txt", std::string_view(small)) + set.add("b.txt", std::string_view(large));
    publish_error = set.publish();
  }
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &old_limit), 0);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(add_error.find((dir / "b.txt").string()), std::string::npos) << add_error;
  EXPECT_NE(add_error.find("File too large"), std::string::npos) << add_error;
  EXPECT_NE(publish_error.find("previous outputs"), std::string::npos) << publish_error;
  EXPECT_EQ(entries(dir), before);
  EXPECT_EQ(slurp(dir / "a.txt"), "first a");
  EXPECT_EQ(slurp(dir / "b.txt"), "first b");
  fs::remove_all(dir);
}

TEST(FileSet, PrepareRemovesOnlyWhatKilledFileSetsLeft) {
  const fs::path dir = fresh_dir("rankslam_file_set_leftovers");
  publish_set(dir, "first a", "first b");
  const std::string published = fs::read_symlink(dir / "latest").string();
  const std::string dead = std::to_string(dead_pid());
  const std::string alive = std::to_string(::getppid());
  // What a kill -9 leaves: a staged set, a half-swapped link, a file of the single-file writer.
  fs::create_directories(dir / ("set-7." + dead));
  std::ofstream(dir / ("set-7." + dead) / "a.txt") << "staged";
  fs::create_symlink("set-7." + dead, dir / ("latest.tmp." + dead));
  fs::create_symlink("latest/a.txt", dir / ("a.txt.tmp." + dead));
  std::ofstream(dir / ("b.txt.tmp." + dead)) << "half";
  // Another process' set being written, and the user's own files that look alike.
  fs::create_directories(dir / ("set-8." + alive));
  std::ofstream(dir / ("notes.txt.tmp." + dead)) << "the user's";
  std::ofstream(dir / ("set-9." + dead)) << "a file, not a set";
  fs::create_directories(dir / "set-x");
  fs::create_directories(dir / "run-1");
  const std::set<std::string> kept = {"a.txt",          "b.txt", "latest", published, "set-8." + alive,
                                       "notes.txt.tmp." + dead, "set-9." + dead, "set-x", "run-1"};

  EXPECT_EQ(prepare_output_directory(dir), "");
  EXPECT_EQ(entries(dir), kept);
  EXPECT_EQ(slurp(dir / "a.txt"), "first a");
  fs::remove_all(dir);
}

TEST(FileSet, PrepareNamesADirectoryThatCannotBeCreatedOrWritten) {
  const fs::path dir = fresh_dir("rankslam_file_set_unwritable");
  std::ofstream(dir / "plain") << "a regular file";
  std::string error = prepare_output_directory(dir / "plain" / "out");
  EXPECT_NE(error.find((dir / "plain" / "out").string()), std::string::npos) << error;
  error = prepare_output_directory(dir / "plain");
  EXPECT_NE(error.find((dir / "plain").string()), std::string::npos) << error;

  // A directory that exists but takes no file, even for root: the test write finds it.
  rlimit old_limit{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old_limit), 0);
  rlimit limit = old_limit;
  limit.rlim_cur = 0;
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limit), 0);
  error = prepare_output_directory(dir / "out");
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &old_limit), 0);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(error.find((dir / "out").string()), std::string::npos) << error;
  EXPECT_NE(error.find("File too large"), std::string::npos) << error;
  EXPECT_TRUE(fs::is_empty(dir / "out"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rankslam::hal
