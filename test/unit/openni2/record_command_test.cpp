#include "commands.hpp"
#include "exit_codes.hpp"
#include "oni_fixture.hpp"
#include "../hal/recording_fixture.hpp"

#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"

#include <gtest/gtest.h>

#include <fstream>

namespace rankslam::app {
namespace {

using namespace std::chrono_literals;

// `rankslam record` from an .oni recording played through OpenNI2's file device, then the
// result opened by the replay driver.
TEST(RecordCommand, RecordsAnOniPlaybackIntoARecordingTheReplayDriverOpens) {
  const auto dir = openni2::test::fresh_directory("record_command");
  const auto oni = dir / "source.oni";
  ASSERT_EQ(openni2::test::record_dummy_oni(oni, 800), "");
  std::ofstream(dir / "calibration.yaml") << "depth_scale: 1000\ncameras:\n  rgb:\n    model: pinhole\n"
                                             "    width: 320\n    height: 240\n    intrinsics: [260, 260, 159.5, 119.5]\n";
  std::ofstream(dir / "robot.yaml") << "camera:\n  source: openni2:" << oni.string()
                                    << "\n  calibration: calibration.yaml\n  width: 320\n  height: 240\n"
                                       "  replay_rate: 1.0\n";
  RecordArgs args;
  args.out = dir / "take";
  args.config = dir / "robot.yaml";
  args.seconds = 20.0;  // the .oni ends long before
  ASSERT_EQ(run_record(args), kExitOk);

  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(args.out, recording), "");
  EXPECT_GE(recording.frames.size(), 10U);
  EXPECT_TRUE(recording.can_frames.empty());  // no CAN interface in the configuration
  replay::ReplayDepthCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  hal::RgbdFrame frame;
  std::size_t frames = 0;
  double previous = 0.0;
  while (camera.read(frame, 2000ms) == hal::ReadStatus::kOk) {
    ++frames;
    EXPECT_GT(frame.stamp_s, previous);
    EXPECT_EQ(frame.depth.at<std::uint16_t>(0, 3), 2000);
    previous = frame.stamp_s;
  }
  EXPECT_EQ(frames, recording.frames.size());
  EXPECT_EQ(camera.counters().corrupt, 0U);

  // A second run into the same directory is refused: recordings are never overwritten.
  EXPECT_EQ(run_record(args), kExitOutput);

  // A wide-angle device needs its calibration: refused by name before anything is recorded.
  std::ofstream(dir / "wide.yaml") << "camera:\n  source: openni2:" << oni.string()
                                   << "\n  calibration: calibration.yaml\n  width: 320\n  height: 240\n"
                                      "wide_camera: {device: /dev/video99}\n";
  args.out = dir / "wide_take";
  args.config = dir / "wide.yaml";
  testing::internal::CaptureStderr();
  EXPECT_EQ(run_record(args), kExitInput);
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("wide_camera.device needs cameras.fisheye"), std::string::npos) << said;
  EXPECT_FALSE(std::filesystem::exists(args.out));
  std::filesystem::remove_all(dir);
}

// A played recording's wide-angle images are recorded with its frames, each of them.
TEST(RecordCommand, AReplaySourceRecordsItsWideAngleImages) {
  const auto source = test::write_small_recording("rankslam_record_wide_source", 9, true, true);
  test::add_wide_images(source, {100.0, 100.1, 100.2});
  const auto dir = openni2::test::fresh_directory("record_wide");
  std::ofstream(dir / "robot.yaml") << "camera:\n  source: replay:" << source.string() << "\n  replay_rate: 0\n";
  RecordArgs args;
  args.out = dir / "take";
  args.config = dir / "robot.yaml";
  ASSERT_EQ(run_record(args), kExitOk);
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(args.out, recording), "");
  EXPECT_EQ(recording.frames.size(), 9U);
  ASSERT_EQ(recording.fisheye.size(), 3U);
  ASSERT_TRUE(recording.calibration.fisheye.has_value());
  EXPECT_NEAR(recording.fisheye[2].stamp_s, 100.2, 1e-6);

  // A live wide-angle device beside a played recording is refused before anything is recorded:
  // their stamps have no clock in common.
  std::ofstream(dir / "device.yaml") << "camera:\n  source: replay:" << (dir / "take").string()
                                     << "\nwide_camera: {device: /dev/video99, width: 32, height: 24}\n";
  args.out = dir / "take2";
  args.config = dir / "device.yaml";
  testing::internal::CaptureStderr();
  EXPECT_EQ(run_record(args), kExitInput);
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("wide_camera.device with camera.source replay"), std::string::npos) << said;
  EXPECT_FALSE(std::filesystem::exists(args.out));
  std::filesystem::remove_all(dir);
  std::filesystem::remove_all(source);
}

TEST(RecordCommand, MissingOniFileIsAnInputError) {
  const auto dir = openni2::test::fresh_directory("record_missing");
  std::ofstream(dir / "robot.yaml") << "camera:\n  source: openni2:" << (dir / "absent.oni").string() << "\n";
  RecordArgs args;
  args.out = dir / "take";
  args.config = dir / "robot.yaml";
  EXPECT_EQ(run_record(args), kExitInput);
  EXPECT_FALSE(std::filesystem::exists(args.out));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rankslam::app
