// The rankslam executable on damaged or hostile recordings: every bad input ends in a named
// warning or a named error with the documented exit code, never a crash, a hang or unbounded
// memory. Each test damages its own copy of a small simulated recording.
#include "cli_support.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <sys/wait.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

using cli_test::CommandResult;
using cli_test::slurp;

// Runs rankslam under a time limit: a run that hangs ends with timeout's 124 (or 137 once killed).
CommandResult run(const std::string& arguments, int timeout_s = 120) {
  return cli_test::run_shell("timeout -k 5 " + std::to_string(timeout_s) + " " + std::string(RANKSLAM_EXE) + " " +
                             arguments);
}

std::vector<std::string> lines_of(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

void write_lines(const fs::path& path, const std::vector<std::string>& lines) {
  std::ofstream out(path, std::ios::trunc);
  for (const auto& line : lines) out << line << "\n";
}

// Field `index` (0-based) of a whitespace-separated line.
std::string field(const std::string& line, int index) {
  std::istringstream fields(line);
  std::string value;
  for (int i = 0; i <= index; ++i) fields >> value;
  return value;
}

// A fresh 20-frame corridor-loop recording (colour, depth, can.log, ground truth) named `name`.
fs::path simulated(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("rankslam_input_" + name);
  fs::remove_all(dir);
  const auto result = run("simulate corridor-loop -o " + dir.string() + " -n 20");
  EXPECT_EQ(result.exit_code, 0) << result.output;
  fs::remove_all(dir.string() + "_out");
  return dir;
}

fs::path out_of(const fs::path& recording) { return recording.string() + "_out"; }

CommandResult replay(const fs::path& recording, const std::string& extra = "", int timeout_s = 120) {
  return run("replay " + recording.string() + " --out " + out_of(recording).string() + " --quiet " + extra, timeout_s);
}

// Points line `line` (0-based) of associations.txt's colour image at `file`.
void set_colour_file(const fs::path& recording, std::size_t line, const std::string& file) {
  auto lines = lines_of(recording / "associations.txt");
  std::istringstream fields(lines.at(line));
  std::string rgb_stamp, rgb_file, depth_stamp, depth_file;
  fields >> rgb_stamp >> rgb_file >> depth_stamp >> depth_file;
  lines[line] = rgb_stamp + " " + file + " " + depth_stamp + " " + depth_file;
  write_lines(recording / "associations.txt", lines);
}

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(CliInput, AnImageThatIsADirectoryIsSkippedAndCounted) {
  const fs::path recording = simulated("dir_image");
  set_colour_file(recording, 2, "rgb");
  const auto result = replay(recording);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(has(result.output, (recording / "rgb").string() + ": a directory")) << result.output;
  EXPECT_TRUE(has(result.output, "frame 2")) << result.output;
  const std::string report = slurp(out_of(recording) / "report.json");
  EXPECT_TRUE(has(report, "\"skipped_frames\": 1")) << report;
  EXPECT_TRUE(has(report, "\"frames\": 19")) << report;
}

TEST(CliInput, AHugeSparseImageFileIsSkippedUnread) {
  const fs::path recording = simulated("sparse_image");
  {
    std::ofstream(recording / "rgb" / "big.png");
  }
  fs::resize_file(recording / "rgb" / "big.png", std::uintmax_t{20} << 30U);
  set_colour_file(recording, 2, "rgb/big.png");
  const auto result = replay(recording);
  fs::remove(recording / "rgb" / "big.png");
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(has(result.output, "big.png: 21474836480 bytes, more than the 64 MiB")) << result.output;
  EXPECT_TRUE(has(slurp(out_of(recording) / "report.json"), "\"skipped_frames\": 1"));
}

TEST(CliInput, AFifoAsImageIsSkippedWithoutWaiting) {
  const fs::path recording = simulated("fifo_image");
  ASSERT_EQ(::mkfifo((recording / "rgb" / "fifo.png").c_str(), 0600), 0);
  set_colour_file(recording, 2, "rgb/fifo.png");
  const auto result = replay(recording, "", 60);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(has(result.output, "fifo.png: a FIFO, not a regular file")) << result.output;
  EXPECT_TRUE(has(slurp(out_of(recording) / "report.json"), "\"skipped_frames\": 1"));
}

TEST(CliInput, AFifoAsListFileOrCanLogIsRefusedByName) {
  for (const std::string name : {"can.log", "associations.txt", "groundtruth.txt", "calibration.yaml"}) {
    const fs::path recording = simulated("fifo_list");
    fs::remove(recording / name);
    ASSERT_EQ(::mkfifo((recording / name).c_str(), 0600), 0);
    const auto result = replay(recording, "", 60);
    EXPECT_EQ(result.exit_code, 3) << name << "\n" << result.output;
    EXPECT_TRUE(has(result.output, (recording / name).string() + ": a FIFO")) << name << "\n" << result.output;
  }
}

TEST(CliInput, ADeviceAsCanLogIsRefusedByName) {
  const fs::path recording = simulated("devzero_can");
  fs::remove(recording / "can.log");
  fs::create_symlink("/dev/zero", recording / "can.log");
  const auto result = replay(recording, "", 60);
  EXPECT_EQ(result.exit_code, 3) << result.output;
  EXPECT_TRUE(has(result.output, (recording / "can.log").string() + ": a character device")) << result.output;
}

TEST(CliInput, AnOversizedListFileIsRefusedByName) {
  const fs::path recording = simulated("big_list");
  fs::resize_file(recording / "associations.txt", (std::uintmax_t{64} << 20U) + 1);
  const auto result = replay(recording);
  EXPECT_EQ(result.exit_code, 3) << result.output;
  EXPECT_TRUE(has(result.output, (recording / "associations.txt").string() + ": 67108865 bytes, more than the 64 MiB"))
      << result.output;
}

// A PNG header, with valid checksums, declaring a colour image of width x height and no pixels.
std::string png_declaring(std::uint32_t width, std::uint32_t height) {
  const auto crc32 = [](const std::string& bytes) {
    std::uint32_t crc = 0xFFFFFFFFU;
    for (const char c : bytes) {
      crc ^= static_cast<unsigned char>(c);
      for (int k = 0; k < 8; ++k) crc = (crc >> 1U) ^ (0xEDB88320U & (0U - (crc & 1U)));
    }
    return crc ^ 0xFFFFFFFFU;
  };
  const auto u32 = [](std::uint32_t value) {
    return std::string{static_cast<char>(value >> 24U), static_cast<char>(value >> 16U), static_cast<char>(value >> 8U),
                       static_cast<char>(value)};
  };
  const auto chunk = [&](const std::string& type, const std::string& data) {
    return u32(static_cast<std::uint32_t>(data.size())) + type + data + u32(crc32(type + data));
  };
  return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", u32(width) + u32(height) + std::string("\x08\x02\0\0\0", 5)) +
         chunk("IEND", "");
}

TEST(CliInput, AnImageOfTheWrongSizeIsRefusedFromItsHeaderBeforeDecoding) {
  const fs::path recording = simulated("huge_png");
  std::ofstream(recording / "rgb" / "huge.png", std::ios::binary) << png_declaring(30000, 30000);
  set_colour_file(recording, 2, "rgb/huge.png");
  const auto result = replay(recording);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  // The size comes from the header: the decoder, which would allocate 2.7 GB first, never runs.
  EXPECT_TRUE(has(result.output, "huge.png: 30000x30000 but the calibration says 640x480")) << result.output;
  EXPECT_TRUE(has(slurp(out_of(recording) / "report.json"), "\"skipped_frames\": 1"));
}

TEST(CliInput, AThreeChannelDepthImageIsSkipped) {
  const fs::path recording = simulated("depth3");
  const std::string depth_file = field(lines_of(recording / "associations.txt").at(2), 3);
  const cv::Mat depth = cv::imread((recording / depth_file).string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(depth.type(), CV_16UC1);
  cv::Mat three;
  cv::merge(std::vector<cv::Mat>{depth, depth, depth}, three);
  ASSERT_TRUE(cv::imwrite((recording / depth_file).string(), three));
  const auto result = replay(recording);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(has(result.output, depth_file + ": 3 channels of 16 bits")) << result.output;
  EXPECT_TRUE(has(slurp(out_of(recording) / "report.json"), "\"skipped_frames\": 1"));
}

TEST(CliInput, ARepeatedAssociationsLineIsReplayedOnce) {
  const fs::path recording = simulated("dup_lines");
  auto lines = lines_of(recording / "associations.txt");
  lines.insert(lines.begin() + 3, lines[2]);
  write_lines(recording / "associations.txt", lines);
  const auto result = replay(recording);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(has(result.output, "associations.txt:4: colour stamp already on line 3, line dropped")) << result.output;
  EXPECT_TRUE(has(slurp(out_of(recording) / "report.json"), "\"frames\": 20,"));
}

TEST(CliInput, ARecordingWithNoReadableFrameIsAnInputError) {
  const fs::path recording = simulated("unreadable");
  for (const auto& entry : fs::directory_iterator(recording / "rgb")) std::ofstream(entry.path()) << "x\n";
  const auto result = replay(recording);
  EXPECT_EQ(result.exit_code, 3) << result.output;
  EXPECT_TRUE(has(result.output, "no frame of " + recording.string() + " could be read")) << result.output;
}

TEST(CliInput, EvalOfTooFewPosesIsAnInputError) {
  const fs::path dir = fs::temp_directory_path() / "rankslam_input_eval";
  fs::remove_all(dir);
  fs::create_directories(dir);
  std::ofstream(dir / "gt.txt") << "1.0 0 0 0 0 0 0 1\n2.0 1 0 0 0 0 0 1\n";
  const auto result = run("eval " + (dir / "gt.txt").string() + " " + (dir / "gt.txt").string());
  EXPECT_EQ(result.exit_code, 3) << result.output;
  EXPECT_TRUE(has(result.output, (dir / "gt.txt").string())) << result.output;
  EXPECT_TRUE(has(result.output, "at least 3 associated poses")) << result.output;
  EXPECT_TRUE(has(result.output, "found 2")) << result.output;
}

TEST(CliInput, WheelFramesOfTheWrongLengthAreCountedAndNamed) {
  const fs::path recording = simulated("bad_wheel");
  auto lines = lines_of(recording / "can.log");
  lines.at(4) = lines.at(4).substr(0, lines.at(4).find('#') + 5);  // 2 data bytes instead of 8
  write_lines(recording / "can.log", lines);
  const auto result = replay(recording);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(has(result.output, "can.log: 1 wheel frames (identifier 0x101) are not 8 bytes long")) << result.output;
  EXPECT_TRUE(has(result.output, "1700000000.040000 s with 2 bytes")) << result.output;
  EXPECT_TRUE(has(slurp(out_of(recording) / "report.json"), "\"wheel_frames_malformed\": 1,"));
}

TEST(CliInput, ACanStampBeyondTheClockIsAMalformedLine) {
  const fs::path recording = simulated("can_stamp");
  auto lines = lines_of(recording / "can.log");
  lines.at(4).replace(0, lines.at(4).find(')') + 1, "(99999999999.000000)");
  write_lines(recording / "can.log", lines);
  const auto result = replay(recording);
  ASSERT_EQ(result.exit_code, 0) << result.output;
  EXPECT_TRUE(has(result.output, "can.log:5: not a candump -l frame, skipped")) << result.output;
}

TEST(CliInput, ARateThatWouldOverflowThePacingIsAUsageError) {
  const fs::path recording = simulated("rate");
  for (const char* rate : {"1e-300", "1e300", "0.0001"}) {
    const auto result = replay(recording, std::string("--rate ") + rate, 60);
    EXPECT_EQ(result.exit_code, 2) << rate << "\n" << result.output;
    EXPECT_TRUE(has(result.output, "--rate")) << rate << "\n" << result.output;
  }
}

TEST(CliInput, ASymlinkLoopIsAnInputErrorNamingTheFile) {
  for (const std::string name : {"associations.txt", "groundtruth.txt"}) {
    const fs::path recording = simulated("symlink_loop");
    fs::remove(recording / name);
    fs::create_symlink("loop_b", recording / "loop_a");
    fs::create_symlink("loop_a", recording / "loop_b");
    fs::create_symlink("loop_a", recording / name);
    const auto result = replay(recording);
    EXPECT_EQ(result.exit_code, 3) << name << "\n" << result.output;
    EXPECT_TRUE(has(result.output, (recording / name).string())) << name << "\n" << result.output;
  }
}

TEST(CliInput, AnOutputFolderInASymlinkLoopIsAnOutputErrorNamingIt) {
  const fs::path recording = simulated("out_loop");
  const fs::path out = out_of(recording);
  fs::create_symlink(out.filename().string() + "_b", out);
  fs::create_symlink(out.filename(), out.string() + "_b");
  const auto result = run("replay " + recording.string() + " --out " + out.string() + " --quiet");
  fs::remove(out.string() + "_b");
  fs::remove(out);
  EXPECT_EQ(result.exit_code, 4) << result.output;
  EXPECT_TRUE(has(result.output, "cannot create output directory " + out.string())) << result.output;
}

}  // namespace
