#include "robot_config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace rankslam::app {
namespace {

class RobotConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::path(::testing::TempDir()) / ("robot_config_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  std::filesystem::path write(const std::string& text) {
    const auto path = dir_ / "robot.yaml";
    std::ofstream(path) << text;
    return path;
  }

  std::string load(const std::string& text, RobotConfig& config) { return load_robot_config(write(text), config); }

  std::filesystem::path dir_;
};

TEST_F(RobotConfigTest, ReadsEverySectionAndResolvesRelativePaths) {
  RobotConfig config;
  const std::string error = load(R"(
robot: {name: test}
camera: {source: "replay:rec/one", replay_rate: 0, max_frames: 5, exit_after_end_s: -1}
can: {interface: vcan0, play_wheel_frames: false}
output: {pose_rate_hz: 25, heartbeat_rate_hz: 2, watchdog_timeout_s: 0.3, lost_after_failed_frames: 4, dir: out, max_trajectory_poses: 10,
         realtime_priority: 20}
slam: {orb_features: 500}
)", config);
  ASSERT_EQ(error, "");
  EXPECT_EQ(config.camera_source, CameraSource::kReplay);
  EXPECT_EQ(config.camera_location, (dir_ / "rec/one").lexically_normal().string());
  EXPECT_DOUBLE_EQ(config.replay_rate, 0.0);
  EXPECT_EQ(config.max_frames, 5U);
  EXPECT_DOUBLE_EQ(config.exit_after_end_s, -1.0);
  EXPECT_EQ(config.can_interface, "vcan0");
  EXPECT_FALSE(config.play_wheel_frames);
  EXPECT_DOUBLE_EQ(config.output.pose_rate_hz, 25.0);
  EXPECT_DOUBLE_EQ(config.output.heartbeat_rate_hz, 2.0);
  EXPECT_DOUBLE_EQ(config.output.watchdog_timeout_s, 0.3);
  EXPECT_EQ(config.output.lost_after_failed_frames, 4);
  EXPECT_EQ(config.output_dir, dir_ / "out");
  EXPECT_EQ(config.max_trajectory_poses, 10U);
  EXPECT_EQ(config.output_realtime_priority, 20);
  EXPECT_NE(describe_robot_config(config).find("output.pose_rate_hz = 25 Hz"), std::string::npos);
}

TEST_F(RobotConfigTest, OpenNI2SourceTakesAnOptionalUri) {
  RobotConfig config;
  ASSERT_EQ(load("camera: {source: 'openni2:'}\n", config), "");
  EXPECT_EQ(config.camera_source, CameraSource::kOpenNI2);
  EXPECT_EQ(config.camera_location, "");
  ASSERT_EQ(load("camera: {source: 'openni2:/data/a.oni'}\n", config), "");
  EXPECT_EQ(config.camera_location, "/data/a.oni");
}

TEST_F(RobotConfigTest, ErrorsNameTheKey) {
  const auto error_of = [&](const std::string& text) {
    RobotConfig config;
    return load(text, config);
  };
  EXPECT_NE(error_of("can: {interface: can0}\n").find("camera.source is missing"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'usb:1'}\n").find("camera.source 'usb:1'"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:'}\n").find("needs a recording directory"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r', speed: 2}\n").find("camera.speed is not a known parameter"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\nvideo: {}\n").find("'video' is not a known section"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\noutput: {pose_rate_hz: 0}\n").find("output.pose_rate_hz"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\noutput: {pose_rate_hz: fast}\n").find("output.pose_rate_hz is not a valid value"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\noutput: {realtime_priority: 50}\n").find("output.realtime_priority"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\noutput: {realtime_priority: -1}\n").find("output.realtime_priority"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\ncan: {interface: ''}\n").find("can.interface"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r', replay_rate: -1}\n").find("camera.replay_rate"), std::string::npos);
  EXPECT_NE(error_of("camera: [1, 2]\n").find("'camera' must be a map"), std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'\n").find("robot.yaml"), std::string::npos);
}

TEST_F(RobotConfigTest, ExampleRobotConfigurationLoads) {
  RobotConfig config;
  const auto example = std::filesystem::path(RANKSLAM_SOURCE_DIR) / "deploy/config/example-robot.yaml";
  ASSERT_EQ(load_robot_config(example, config), "");
  EXPECT_EQ(config.can_interface, "can0");
  EXPECT_DOUBLE_EQ(config.output.pose_rate_hz, 50.0);
  // Installed as /etc/rankslam/robot.yaml: the live sensor, not a recording that is not there.
  EXPECT_EQ(config.camera_source, CameraSource::kOpenNI2);
  EXPECT_EQ(config.camera_location, "");
  EXPECT_DOUBLE_EQ(config.status_interval_s, 60.0);
  EXPECT_EQ(config.map_file, "/var/lib/rankslam/map.rsm");  // in the service's state directory
  EXPECT_DOUBLE_EQ(config.checkpoint_s, 30.0);

  RobotConfig replay;
  ASSERT_EQ(load_robot_config(std::filesystem::path(RANKSLAM_SOURCE_DIR) / "deploy/config/replay-robot.yaml", replay), "");
  EXPECT_EQ(replay.camera_source, CameraSource::kReplay);
  EXPECT_EQ(replay.can_interface, "vcan0");
}

TEST_F(RobotConfigTest, StatusIntervalIsRangeChecked) {
  RobotConfig config;
  EXPECT_EQ(load("camera: {source: 'replay:r'}\noutput: {status_interval_s: 0}\n", config), "");
  EXPECT_DOUBLE_EQ(config.status_interval_s, 0.0);
  const auto error_of = [&](const std::string& text) {
    RobotConfig rejected;
    return load(text, rejected);
  };
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\noutput: {status_interval_s: -1}\n").find("output.status_interval_s"),
            std::string::npos);
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\noutput: {status_interval_s: 86401}\n").find("output.status_interval_s"),
            std::string::npos);
}

TEST_F(RobotConfigTest, MapFileIsTakenFromTheFilesDirectoryAndTheCheckpointIntervalRangeChecked) {
  RobotConfig config;
  ASSERT_EQ(load("camera: {source: 'replay:r'}\n", config), "");
  EXPECT_TRUE(config.map_file.empty());
  EXPECT_DOUBLE_EQ(config.checkpoint_s, 30.0);
  ASSERT_EQ(load("camera: {source: 'replay:r'}\nmap: {file: maps/m.rsm, checkpoint_s: 0}\n", config), "");
  EXPECT_EQ(config.map_file, dir_ / "maps/m.rsm");
  EXPECT_DOUBLE_EQ(config.checkpoint_s, 0.0);
  const auto error_of = [&](const std::string& text) {
    RobotConfig rejected;
    return load(text, rejected);
  };
  for (const char* bad : {"map: {checkpoint_s: -1}\n", "map: {checkpoint_s: 86401}\n", "map: {checkpoint_s: .nan}\n",
                          "map: {checkpoint_s: often}\n"}) {
    EXPECT_NE(error_of(std::string("camera: {source: 'replay:r'}\n") + bad).find("map.checkpoint_s"), std::string::npos) << bad;
  }
  EXPECT_NE(error_of("camera: {source: 'replay:r'}\nmap: {path: m.rsm}\n").find("map.path"), std::string::npos);
}

}  // namespace
}  // namespace rankslam::app
