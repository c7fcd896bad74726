#include "rankslam/hal/atomic_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace rankslam::hal {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

TEST(AtomicFile, ReplacesWholeFileAndLeavesNoTemporary) {
  const fs::path dir = fs::temp_directory_path() / "rankslam_atomic_test";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path file = dir / "out.txt";
  ASSERT_EQ(write_file_atomically(file, std::string_view("first version, longer")), "");
  ASSERT_EQ(write_file_atomically(file, std::string_view("second")), "");
  EXPECT_EQ(slurp(file), "second");
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 1);
  fs::remove_all(dir);
}

TEST(AtomicFile, ReportsUnwritableDirectoryByName) {
  const std::string error = write_file_atomically("/nonexistent-dir/out.txt", std::string_view("x"));
  EXPECT_NE(error.find("/nonexistent-dir/out.txt"), std::string::npos) << error;
}

}  // namespace
}  // namespace rankslam::hal
