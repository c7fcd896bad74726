#include "config_file.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

namespace rankslam::app {
namespace {

namespace fs = std::filesystem;

fs::path write_yaml(const std::string& name, const std::string& text) {
  const fs::path path = fs::temp_directory_path() / name;
  std::ofstream(path) << text;
  return path;
}

TEST(ConfigFile, OverridesOnlyTheGivenKeys) {
  slam::SlamConfig config;
  const auto path = write_yaml("rankslam_cfg_ok.yaml", "slam:\n  orb_features: 600\n  max_depth_m: 3.5\n");
  ASSERT_EQ(load_slam_config(path, config), "");
  EXPECT_EQ(config.orb_features, 600);
  EXPECT_DOUBLE_EQ(config.max_depth_m, 3.5);
  EXPECT_DOUBLE_EQ(config.min_depth_m, slam::SlamConfig{}.min_depth_m);
}

TEST(ConfigFile, ShippedDefaultFileMatchesTheBuiltInDefaults) {
  slam::SlamConfig config;
  ASSERT_EQ(load_slam_config(fs::path(RANKSLAM_SOURCE_DIR) / "deploy/config/default.yaml", config), "");
  EXPECT_EQ(describe_slam_config(config), describe_slam_config(slam::SlamConfig{}));
}

TEST(ConfigFile, ErrorsNameFileAndKey) {
  slam::SlamConfig config;
  auto path = write_yaml("rankslam_cfg_range.yaml", "slam:\n  orb_features: 5\n");
  std::string error = load_slam_config(path, config);
  EXPECT_NE(error.find("slam.orb_features"), std::string::npos) << error;
  EXPECT_NE(error.find("rankslam_cfg_range.yaml"), std::string::npos) << error;

  path = write_yaml("rankslam_cfg_type.yaml", "slam:\n  max_depth_m: far\n");
  error = load_slam_config(path, config);
  EXPECT_NE(error.find("slam.max_depth_m"), std::string::npos) << error;

  path = write_yaml("rankslam_cfg_unknown.yaml", "slam:\n  max_depth: 3\n");
  error = load_slam_config(path, config);
  EXPECT_NE(error.find("slam.max_depth "), std::string::npos) << error;

  path = write_yaml("rankslam_cfg_syntax.yaml", "slam: [unclosed\n");
  EXPECT_FALSE(load_slam_config(path, config).empty());

  path = write_yaml("rankslam_cfg_order.yaml", "slam:\n  min_depth_m: 3.0\n  max_depth_m: 2.0\n");
  EXPECT_FALSE(load_slam_config(path, config).empty());
}

TEST(ConfigFile, ShippedDefaultFileMatchesTheBuiltInWheelOdometryDefaults) {
  nav::WheelOdometryConfig config;
  config.history_capacity = 7;  // the file must set it back
  ASSERT_EQ(load_wheel_config(fs::path(RANKSLAM_SOURCE_DIR) / "deploy/config/default.yaml", config), "");
  EXPECT_EQ(describe_wheel_config(config), describe_wheel_config(nav::WheelOdometryConfig{}));
}

TEST(ConfigFile, WheelOdometrySectionOverridesItsKeysAndNamesBadOnes) {
  nav::WheelOdometryConfig config;
  auto path = write_yaml("rankslam_cfg_wheels.yaml", "wheel_odometry:\n  wheel_variance_per_m: 0.0004\n");
  ASSERT_EQ(load_wheel_config(path, config), "");
  EXPECT_DOUBLE_EQ(config.wheel_variance_per_m, 0.0004);
  EXPECT_EQ(config.history_capacity, nav::WheelOdometryConfig{}.history_capacity);

  path = write_yaml("rankslam_cfg_wheels_range.yaml", "wheel_odometry:\n  max_frame_gap_s: 5\n");
  std::string error = load_wheel_config(path, config);
  EXPECT_NE(error.find("wheel_odometry.max_frame_gap_s"), std::string::npos) << error;
  EXPECT_NE(error.find("rankslam_cfg_wheels_range.yaml"), std::string::npos) << error;

  path = write_yaml("rankslam_cfg_wheels_unknown.yaml", "wheel_odometry:\n  wheel_radius_m: 0.1\n");
  error = load_wheel_config(path, config);
  EXPECT_NE(error.find("wheel_odometry.wheel_radius_m"), std::string::npos) << error;

  // Every range the loader accepts is one the odometry accepts.
  nav::WheelOdometryConfig extreme;
  extreme.visit_parameters([](auto, auto& field, auto min, auto, auto, auto) { field = min; });
  EXPECT_EQ(nav::validate(extreme, hal::WheelGeometry{}), "");
  extreme.visit_parameters([](auto, auto& field, auto, auto max, auto, auto) { field = max; });
  EXPECT_EQ(nav::validate(extreme, hal::WheelGeometry{}), "");
}

TEST(ConfigFile, DescriptionListsEveryParameterWithItsDoc) {
  const std::string text = describe_slam_config(slam::SlamConfig{});
  EXPECT_NE(text.find("slam.orb_features = 1000  # ORB keypoints detected per frame"), std::string::npos) << text;
  EXPECT_NE(text.find("slam.max_depth_m = 4 m"), std::string::npos) << text;
}

}  // namespace
}  // namespace rankslam::app
