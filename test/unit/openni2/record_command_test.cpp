#include "commands.hpp"
#include "exit_codes.hpp"
#include "oni_fixture.hpp"

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
  std::filesystem::remove_all(dir);
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
