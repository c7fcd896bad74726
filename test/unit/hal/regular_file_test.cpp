#include "rankslam/hal/regular_file.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <fstream>

namespace rankslam::hal {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

TEST(RegularFile, ReadsARegularFileWholeIntoTheReusedBuffer) {
  const fs::path dir = fresh_dir("rankslam_regular_file");
  std::ofstream(dir / "a.txt") << "hello\nworld\n";
  std::vector<unsigned char> bytes;
  bytes.reserve(1024);
  const auto* const storage = bytes.data();
  ASSERT_EQ(read_regular_file(dir / "a.txt", 1024, bytes), "");
  EXPECT_EQ(std::string(bytes.begin(), bytes.end()), "hello\nworld\n");
  EXPECT_EQ(bytes.data(), storage);
  std::string text;
  ASSERT_EQ(read_regular_file(dir / "a.txt", 12, text), "");
  EXPECT_EQ(text, "hello\nworld\n");
}

TEST(RegularFile, RefusesWhatIsNotARegularFileWithoutWaiting) {
  const fs::path dir = fresh_dir("rankslam_regular_refused");
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0600), 0);
  std::string text;
  // Opening a FIFO with no writer would block a plain open() for ever.
  EXPECT_EQ(read_regular_file(dir / "fifo", 1024, text), (dir / "fifo").string() + ": a FIFO, not a regular file");
  EXPECT_EQ(read_regular_file(dir, 1024, text), dir.string() + ": a directory, not a regular file");
  EXPECT_EQ(read_regular_file("/dev/zero", 1024, text), "/dev/zero: a character device, not a regular file");
  EXPECT_EQ(check_regular_file(dir / "fifo", 1024), (dir / "fifo").string() + ": a FIFO, not a regular file");
  EXPECT_NE(read_regular_file(dir / "absent", 1024, text).find("cannot open " + (dir / "absent").string()),
            std::string::npos);
}

TEST(RegularFile, RefusesAFileBeyondItsBoundBeforeReadingIt) {
  const fs::path dir = fresh_dir("rankslam_regular_bound");
  std::ofstream(dir / "big") << "x";
  fs::resize_file(dir / "big", std::uintmax_t{20} << 30U);  // sparse: takes no disk
  std::vector<unsigned char> bytes;
  EXPECT_EQ(read_regular_file(dir / "big", std::size_t{64} << 20U, bytes),
            (dir / "big").string() + ": 21474836480 bytes, more than the 64 MiB such a file may have");
  EXPECT_EQ(bytes.capacity(), 0U);
  EXPECT_NE(check_regular_file(dir / "big", std::size_t{64} << 20U).find("21474836480 bytes"), std::string::npos);
  EXPECT_EQ(check_regular_file(dir / "big", std::size_t{32} << 30U), "");
}

TEST(RegularFile, PathExistsTellsASymlinkLoopFromAnAbsentFile) {
  const fs::path dir = fresh_dir("rankslam_regular_exists");
  fs::create_symlink("b", dir / "a");
  fs::create_symlink("a", dir / "b");
  fs::create_symlink("nowhere", dir / "dangling");
  std::ofstream(dir / "file") << "x";
  std::string error;
  EXPECT_TRUE(path_exists(dir / "file", error));
  EXPECT_EQ(error, "");
  EXPECT_FALSE(path_exists(dir / "absent", error));
  EXPECT_FALSE(path_exists(dir / "dangling", error));
  EXPECT_EQ(error, "");
  EXPECT_FALSE(path_exists(dir / "a", error));
  EXPECT_NE(error.find((dir / "a").string() + ": "), std::string::npos) << error;
}

}  // namespace
}  // namespace rankslam::hal
