#include "config_file.hpp"
#include "exit_codes.hpp"
#include "robot_config.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

namespace rankslam::app {
namespace {

namespace fs = std::filesystem;

class ConfigStrictTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("config_strict_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& text) {
    const fs::path path = dir_ / "config.yaml";
    std::ofstream(path, std::ios::trunc) << text;
    return path;
  }

  // load_pipeline_config's exit code for a --config of `text`, as replay calls it.
  int replay_config(const std::string& text) {
    slam::SlamConfig slam_config;
    nav::WheelOdometryConfig wheel_config;
    return load_pipeline_config(write(text), "", slam_config, wheel_config);
  }

  fs::path dir_;
};

// Every floating-point parameter of `config`, set to each non-finite value in turn, is rejected by
// `load` with an error naming the file and section.name.
template <typename Config, typename Write, typename Load>
void expect_non_finite_rejected(Config config, const std::string& section, Write write, Load load) {
  int checked = 0;
  config.visit_parameters([&](auto name_arg, auto& field, auto, auto, auto, auto) {
    if constexpr (std::is_floating_point_v<std::remove_reference_t<decltype(field)>>) {
      const std::string name(name_arg);
      for (const char* value : {".nan", ".inf", "-.inf"}) {
        const fs::path path = write(section + ":\n  " + name + ": " + value + "\n");
        const std::string error = load(path);
        EXPECT_NE(error.find(path.string() + ": " + section + "." + name + " = "), std::string::npos)
            << name << ": " << value << ": " << error;
        EXPECT_NE(error.find("is not a finite number"), std::string::npos) << error;
      }
      ++checked;
    }
  });
  EXPECT_GT(checked, 0) << section;
}

TEST_F(ConfigStrictTest, EveryNonFiniteParameterIsRejectedByFileAndKey) {
  const auto writer = [this](const std::string& text) { return write(text); };
  expect_non_finite_rejected(slam::SlamConfig{}, "slam", writer, [](const fs::path& path) {
    slam::SlamConfig config;
    return load_slam_config(path, config);
  });
  expect_non_finite_rejected(slam::SlamConfig{}.geometry, "geometry", writer, [](const fs::path& path) {
    slam::SlamConfig config;
    return load_slam_config(path, config);
  });
  expect_non_finite_rejected(nav::WheelOdometryConfig{}, "wheel_odometry", writer, [](const fs::path& path) {
    nav::WheelOdometryConfig config;
    return load_wheel_config(path, config);
  });
}

TEST_F(ConfigStrictTest, ANonFiniteValueNeverReachesTheConfiguration) {
  slam::SlamConfig config;
  const double max_depth_m = config.max_depth_m;
  EXPECT_NE(load_slam_config(write("slam:\n  max_depth_m: .nan\n"), config), "");
  EXPECT_EQ(config.max_depth_m, max_depth_m);
  EXPECT_EQ(replay_config("slam:\n  max_depth_m: .nan\n"), kExitInput);
}

TEST_F(ConfigStrictTest, ReportJsonHoldsNullForANonFiniteParameter) {
  slam::SlamConfig config;
  config.map.voxel_m = std::numeric_limits<double>::quiet_NaN();
  config.max_depth_m = std::numeric_limits<double>::infinity();
  const std::string json = slam_config_json(config);
  EXPECT_NE(json.find("\"map_voxel_m\": null"), std::string::npos) << json;
  EXPECT_NE(json.find("\"max_depth_m\": null"), std::string::npos) << json;
  for (const char* bare : {": nan", ": inf", ": -nan", ": -inf"}) EXPECT_EQ(json.find(bare), std::string::npos) << json;
  // Finite values print as before.
  EXPECT_NE(slam_config_json(slam::SlamConfig{}).find("\"max_depth_m\": 4,"), std::string::npos);
}

TEST_F(ConfigStrictTest, ReplayConfigRejectsUnknownSectionsLikeRun) {
  EXPECT_EQ(replay_config("slamm:\n  orb_features: 500\n"), kExitInput);
  EXPECT_EQ(replay_config("camera: {source: 'replay:r'}\n"), kExitInput);
  YAML::Node root;
  const std::string error = read_config_file(write("slamm:\n  orb_features: 500\n"), {}, root);
  EXPECT_NE(error.find("config.yaml: 'slamm' is not a known section"), std::string::npos) << error;
  RobotConfig robot;
  EXPECT_NE(load_robot_config(write("camera: {source: 'replay:r'}\nslamm: {}\n"), robot).find("'slamm' is not a known section"),
            std::string::npos);

  // The files we ship load, each as the command that reads it.
  EXPECT_EQ(replay_config(""), kExitOk);
  slam::SlamConfig slam_config;
  nav::WheelOdometryConfig wheel_config;
  EXPECT_EQ(load_pipeline_config(fs::path(RANKSLAM_SOURCE_DIR) / "deploy/config/default.yaml", "", slam_config,
                                 wheel_config),
            kExitOk);
  EXPECT_EQ(load_pipeline_config(fs::path(RANKSLAM_SOURCE_DIR) / "deploy/config/example-robot.yaml", "", slam_config,
                                 wheel_config, robot_config_sections()),
            kExitOk);
}

TEST_F(ConfigStrictTest, KeysGivenTwiceAreRejectedInEveryConfigFile) {
  EXPECT_EQ(replay_config("slam:\n  orb_features: 500\n  orb_features: 600\n"), kExitInput);
  EXPECT_EQ(replay_config("wheel_odometry: {}\nwheel_odometry: {}\n"), kExitInput);
  slam::SlamConfig config;
  EXPECT_NE(load_slam_config(write("slam:\n  orb_features: 500\n  orb_features: 600\n"), config)
                .find("slam.orb_features is given twice (again at line 3"),
            std::string::npos);
  RobotConfig robot;
  EXPECT_NE(load_robot_config(write("camera: {source: 'replay:a', source: 'replay:b'}\n"), robot)
                .find("camera.source is given twice"),
            std::string::npos);
}

TEST_F(ConfigStrictTest, ComplexKeysWrongTypesAndDeepNestingAreErrorsNotExceptions) {
  const std::string deep = "x: " + std::string(5000, '[') + std::string(5000, ']') + "\n";
  // Whether run's robot configuration loader rejects the text too (it reads no slam section).
  for (const auto& [text, whole_file] : std::vector<std::pair<std::string, bool>>{
           {"slam:\n  ? [a, b]\n  : 1\n", true},
           {"? [a, b]\n: 1\n", true},
           {"just a scalar\n", true},
           {"slam:\n  " + deep, true},
           {"slam: 5\n", false},
           {"geometry: [1]\n", false},
           {"slam:\n  orb_features: {a: 1}\n", false}}) {
    std::string error;
    slam::SlamConfig config;
    EXPECT_NO_THROW(error = load_slam_config(write(text), config)) << text;
    EXPECT_EQ(error.rfind((dir_ / "config.yaml").string() + ": ", 0), 0U) << text << "\n" << error;
    int code = kExitOk;
    EXPECT_NO_THROW(code = replay_config(text)) << text;
    EXPECT_EQ(code, kExitInput) << text;
    if (!whole_file) continue;
    RobotConfig robot;
    EXPECT_NO_THROW(error = load_robot_config(write("camera: {source: 'replay:r'}\n" + text), robot)) << text;
    EXPECT_EQ(error.rfind((dir_ / "config.yaml").string() + ": ", 0), 0U) << text << "\n" << error;
  }
  slam::SlamConfig config;
  EXPECT_NE(load_slam_config(write("x: " + std::string(5000, '[') + std::string(5000, ']') + "\n"), config)
                .find("not valid YAML (nested too deep)"),
            std::string::npos);
}

TEST_F(ConfigStrictTest, RobotConfigNumbersAreFiniteAndInRange) {
  const auto error_of = [&](const std::string& camera, const std::string& output = "{}") {
    RobotConfig config;
    return load_robot_config(write("camera: {source: 'replay:r', " + camera + "}\noutput: " + output + "\n"), config);
  };
  EXPECT_NE(error_of("exit_after_end_s: .nan").find("camera.exit_after_end_s = nan is not a finite number"),
            std::string::npos);
  EXPECT_NE(error_of("exit_after_end_s: .inf").find("camera.exit_after_end_s"), std::string::npos);
  EXPECT_NE(error_of("replay_rate: .nan").find("camera.replay_rate"), std::string::npos);
  EXPECT_NE(error_of("max_frames: -1").find("camera.max_frames"), std::string::npos);
  EXPECT_NE(error_of("fps: 2.5").find("camera.fps is not a valid value"), std::string::npos);
  EXPECT_NE(error_of("width: 5000").find("camera.width = 5000 is outside 1 .. 4096"), std::string::npos);
  EXPECT_NE(error_of("", "{pose_rate_hz: .nan}").find("output.pose_rate_hz = nan is not a finite number"),
            std::string::npos);
  EXPECT_NE(error_of("", "{max_trajectory_poses: 0}").find("output.max_trajectory_poses"), std::string::npos);
  EXPECT_EQ(error_of("exit_after_end_s: -1, replay_rate: 0"), "");
}

}  // namespace
}  // namespace rankslam::app
