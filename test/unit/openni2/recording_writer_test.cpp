#include "oni_fixture.hpp"
#include "rankslam/openni2/openni2_camera.hpp"
#include "rankslam/record/recording_writer.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <fstream>
#include <string>

namespace rankslam::record {
namespace {

using namespace std::chrono_literals;

openni2::OpenNI2Options dummy_options() {
  openni2::OpenNI2Options options;
  options.uri = openni2::test::kDummyUri;
  options.width = 320;
  options.height = 240;
  options.calibration = openni2::test::dummy_calibration();
  return options;
}

int count_lines(const std::filesystem::path& path) {
  std::ifstream in(path);
  int lines = 0;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty() && line[0] != '#') ++lines;
  }
  return lines;
}

TEST(RecordingWriter, RecordsTheDummyDeviceIntoARecordingTheReplayDriverPlays) {
  const auto dir = openni2::test::fresh_directory("record") / "take";
  openni2::OpenNI2Camera camera(dummy_options());
  ASSERT_EQ(camera.open(), "");
  RecordingWriterOptions options;
  options.write_can = true;
  options.can_interface = "vcan0";
  RecordingWriter writer(dir, options);
  ASSERT_EQ(writer.open(camera.calibration()), "");
  hal::RgbdFrame frame;
  std::vector<double> stamps;
  for (int i = 0; i < 12; ++i) {
    ASSERT_EQ(camera.read(frame, 1000ms), hal::ReadStatus::kOk);
    ASSERT_TRUE(writer.push(frame));
    stamps.push_back(frame.stamp_s);
    hal::CanFrame can;
    can.stamp_ns = frame.stamp_ns;
    can.id = 0x101;
    can.length = 2;
    can.data[0] = static_cast<std::uint8_t>(i);
    ASSERT_TRUE(writer.push_can(can));
  }
  camera.close();
  ASSERT_EQ(writer.close(), "");
  EXPECT_EQ(writer.counters().frames_written, 12U);
  EXPECT_EQ(writer.counters().frames_dropped, 0U);
  EXPECT_EQ(writer.counters().can_written, 12U);

  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(dir, recording), "");
  EXPECT_TRUE(recording.warnings.empty());
  ASSERT_EQ(recording.frames.size(), 12U);
  ASSERT_EQ(recording.can_frames.size(), 12U);
  EXPECT_EQ(recording.can_frames[3].data[0], 3);
  EXPECT_NEAR(static_cast<double>(recording.can_frames[3].stamp_ns) * 1e-9, stamps[3], 1e-5);
  EXPECT_EQ(recording.calibration.depth_scale, 1000.0);
  EXPECT_EQ(recording.calibration.rgb.width, 320);
  EXPECT_DOUBLE_EQ(recording.calibration.rgb.fx, 260.0);
  replay::ReplayDepthCamera replay_camera(recording, {});
  ASSERT_EQ(replay_camera.open(), "");
  for (std::size_t i = 0; i < 12; ++i) {
    ASSERT_EQ(replay_camera.read(frame, 2000ms), hal::ReadStatus::kOk) << i;
    EXPECT_NEAR(frame.stamp_s, stamps[i], 1e-6);
    EXPECT_EQ(frame.depth.at<std::uint16_t>(0, 7), 2000);  // PNG is lossless
    EXPECT_EQ(frame.rgb.at<cv::Vec3b>(0, 0)[0], 255);
  }
  EXPECT_EQ(replay_camera.read(frame, 2000ms), hal::ReadStatus::kEndOfStream);
  EXPECT_EQ(replay_camera.counters().corrupt, 0U);
  std::filesystem::remove_all(dir.parent_path());
}

TEST(RecordingWriter, FullQueueDropsAndCountsInsteadOfBlocking) {
  const auto dir = openni2::test::fresh_directory("drops") / "take";
  hal::Calibration calibration = openni2::test::dummy_calibration();
  RecordingWriterOptions options;
  options.frame_queue = 1;
  options.png_compression = 9;  // slow on purpose: the writer falls behind
  RecordingWriter writer(dir, options);
  ASSERT_EQ(writer.open(calibration), "");
  cv::Mat rgb(240, 320, CV_8UC3);
  cv::Mat depth(240, 320, CV_16UC1);
  cv::randu(rgb, 0, 255);
  cv::randu(depth, 0, 5000);
  hal::RgbdFrame frame;
  frame.rgb = rgb;
  frame.depth = depth;
  int accepted = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 40; ++i) {
    frame.sequence = static_cast<std::uint32_t>(i);
    frame.stamp_s = 100.0 + i / 30.0;
    if (writer.push(frame)) ++accepted;
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, 200ms);  // push never waits for the disk
  ASSERT_EQ(writer.close(), "");
  const RecordingCounters counters = writer.counters();
  EXPECT_GT(counters.frames_dropped, 0U);
  EXPECT_EQ(counters.frames_queued, static_cast<std::uint64_t>(accepted));
  EXPECT_EQ(counters.frames_written + counters.frames_dropped, 40U);
  // Every frame the index lists is on disk, and nothing else is listed.
  EXPECT_EQ(count_lines(dir / "associations.txt"), accepted);
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(dir, recording), "");
  EXPECT_EQ(recording.frames.size(), static_cast<std::size_t>(accepted));
  std::filesystem::remove_all(dir.parent_path());
}

TEST(RecordingWriter, WritesTheWideAngleImagesTheReplayPlaysBack) {
  const auto dir = openni2::test::fresh_directory("wide") / "take";
  hal::Calibration calibration = openni2::test::dummy_calibration();
  hal::CameraCalibration fisheye;
  fisheye.model = hal::CameraModel::kFisheye;
  fisheye.width = 160;
  fisheye.height = 120;
  fisheye.fx = fisheye.fy = 50.0;
  fisheye.cx = 79.5;
  fisheye.cy = 59.5;
  calibration.fisheye = fisheye;
  RecordingWriter writer(dir, {});
  ASSERT_EQ(writer.open(calibration), "");
  hal::RgbdFrame frame;
  frame.rgb = cv::Mat(240, 320, CV_8UC3, cv::Scalar::all(9));
  frame.depth = cv::Mat(240, 320, CV_16UC1, cv::Scalar::all(2000));
  for (int i = 0; i < 4; ++i) {
    frame.sequence = static_cast<std::uint32_t>(i);
    frame.stamp_s = 100.0 + i / 10.0;
    ASSERT_TRUE(writer.push(frame));
  }
  std::vector<cv::Mat> images;
  hal::ImageFrame wide;
  for (int i = 0; i < 4; ++i) {
    images.emplace_back(120, 160, CV_8UC3);
    cv::randu(images.back(), 0, 255);
    wide.image = images.back();
    wide.sequence = static_cast<std::uint32_t>(i);
    wide.stamp_s = 100.0 + i / 10.0;
    ASSERT_TRUE(writer.push_wide(wide));
  }
  wide.image = cv::Mat(240, 320, CV_8UC3, cv::Scalar::all(0));
  EXPECT_FALSE(writer.push_wide(wide));  // not the calibrated size
  ASSERT_EQ(writer.close(), "");
  EXPECT_EQ(writer.counters().wide_written, 4U);
  EXPECT_EQ(writer.counters().wide_dropped, 1U);

  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(dir, recording), "");
  ASSERT_EQ(recording.fisheye.size(), 4U);
  ASSERT_TRUE(recording.calibration.fisheye.has_value());
  EXPECT_EQ(recording.calibration.fisheye->model, hal::CameraModel::kFisheye);
  replay::ReplayImageCamera replay_camera(recording, {});
  ASSERT_EQ(replay_camera.open(), "");
  for (std::size_t i = 0; i < 4; ++i) {
    ASSERT_EQ(replay_camera.read(wide, 2000ms), hal::ReadStatus::kOk) << i;
    EXPECT_NEAR(wide.stamp_s, 100.0 + static_cast<double>(i) / 10.0, 1e-6);
    EXPECT_EQ(cv::norm(wide.image, images[i], cv::NORM_INF), 0.0) << i;  // PNG is lossless
  }
  EXPECT_EQ(replay_camera.read(wide, 2000ms), hal::ReadStatus::kEndOfStream);

  // Without a wide-angle camera in the calibration there is nowhere to put one.
  const auto plain = openni2::test::fresh_directory("wide_plain") / "take";
  RecordingWriter plain_writer(plain, {});
  ASSERT_EQ(plain_writer.open(openni2::test::dummy_calibration()), "");
  EXPECT_FALSE(plain_writer.push_wide(wide));
  ASSERT_EQ(plain_writer.close(), "");
  EXPECT_FALSE(std::filesystem::exists(plain / "fisheye.txt"));
  std::filesystem::remove_all(dir.parent_path());
  std::filesystem::remove_all(plain.parent_path());
}

TEST(RecordingWriter, RefusesANonEmptyDirectoryAndNamesIt) {
  const auto dir = openni2::test::fresh_directory("nonempty");
  std::ofstream(dir / "something.txt") << "x";
  RecordingWriter writer(dir, {});
  const std::string error = writer.open(openni2::test::dummy_calibration());
  EXPECT_NE(error.find(dir.string()), std::string::npos) << error;
  EXPECT_NE(error.find("not empty"), std::string::npos) << error;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rankslam::record
