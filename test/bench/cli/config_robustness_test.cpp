// Runs the rankslam executable on configuration and calibration files a user can get wrong: every
// mistake must stop the run with exit 3 and a message naming the file and the key.
#include "cli_support.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;

using namespace cli_test;

// A folder of this test's own: ctest runs the tests in parallel processes, other checkouts may too.
fs::path test_dir() {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir =
      fs::temp_directory_path() / ("rankslam_cli_config_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// A three-frame simulated corridor-loop recording (cameras rgb and fisheye, wheels) in dir/base.
fs::path simulate_base(const fs::path& dir) {
  const fs::path base = dir / "base";
  const auto result = run("simulate corridor-loop --frames 3 --out " + base.string());
  EXPECT_EQ(result.exit_code, 0) << result.output;
  return base;
}

// A copy of `base` whose calibration.yaml has `from` replaced by `to` (the first occurrence).
fs::path with_calibration_edit(const fs::path& base, const std::string& name, const std::string& from,
                               const std::string& to) {
  const fs::path copy = base.parent_path() / name;
  fs::copy(base, copy, fs::copy_options::recursive);
  std::string text = slurp(copy / "calibration.yaml");
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from << " not in\n" << text;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  std::ofstream(copy / "calibration.yaml", std::ios::trunc) << text;
  return copy;
}

// Each test in a folder of its own, removed afterwards.
class CliConfig : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test_dir(); }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

CommandResult replay(const fs::path& recording, const fs::path& out, const std::string& extra = {}) {
  return run("replay " + recording.string() + " --out " + out.string() + " --max-frames 3 --quiet " + extra);
}

void expect_input_error(const CommandResult& result, const std::string& file, const std::string& key) {
  EXPECT_EQ(result.exit_code, 3) << result.output;
  EXPECT_NE(result.output.find(file), std::string::npos) << "file " << file << " not named:\n" << result.output;
  EXPECT_NE(result.output.find(key), std::string::npos) << "key " << key << " not named:\n" << result.output;
  EXPECT_EQ(result.output.find("internal error"), std::string::npos) << result.output;
}

TEST_F(CliConfig, NonFiniteConfigValuesAreRejectedByFileAndKey) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  for (const auto& [key, value] : {std::pair<std::string, std::string>{"slam.max_depth_m", ".nan"},
                                   {"slam.map_voxel_m", ".nan"},
                                   {"slam.keyframe_translation_m", ".inf"},
                                   {"geometry.max_depth_m", "-.inf"},
                                   {"wheel_odometry.wheel_variance_per_m", ".nan"}}) {
    const auto dot = key.find('.');
    const fs::path config = dir / "nan.yaml";
    std::ofstream(config, std::ios::trunc) << key.substr(0, dot) << ":\n  " << key.substr(dot + 1) << ": " << value
                                           << "\n";
    SCOPED_TRACE(key);
    expect_input_error(replay(base, dir / "out", "--config " + config.string()), "nan.yaml", key);
  }
}

TEST_F(CliConfig, UnknownSectionsDuplicateAndComplexKeysAreRejected) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  const auto check = [&](const std::string& text, const std::string& key) {
    const fs::path config = dir / "config.yaml";
    std::ofstream(config, std::ios::trunc) << text;
    SCOPED_TRACE(text);
    expect_input_error(replay(base, dir / "out", "--config " + config.string()), "config.yaml", key);
  };
  check("slam:\n  orb_features: 500\nslamm:\n  orb_features: 500\n", "'slamm' is not a known section (line 3");
  check("slam:\n  orb_features: 500\n  orb_features: 600\n", "slam.orb_features is given twice (again at line 3");
  check("slam:\n  orb_features: 500\nslam:\n  min_inliers: 12\n", "slam is given twice (again at line 3");
  check("slam:\n  ? [a, b]\n  : 1\n", "slam: the key at line 2");
  check("slam: 5\n", "'slam' must be a map (line 1");
  check("slam:\n  orb_features: [500]\n", "slam.orb_features is not a valid value: expected a number, not a list (line 2");
  check("slam:\n\n  orb_features: many\n", "slam.orb_features is not a valid value: 'many' is not a whole number (line 3");
  check("slam:\n  orb_features: 5000000\n", "slam.orb_features = 5000000 is outside");
}

TEST_F(CliConfig, RunRejectsMisspeltSectionsDuplicateKeysAndTypeErrorsByFileLineAndKey) {
  const fs::path& dir = dir_;
  const std::string robot = "camera: {source: 'replay:rec'}\ncan: {interface: vcan0}\n";
  const auto check = [&](const std::string& text, const std::string& key) {
    std::ofstream(dir / "robot.yaml", std::ios::trunc) << robot << text;
    SCOPED_TRACE(text);
    expect_input_error(run("run --config " + (dir / "robot.yaml").string() + " --out " + (dir / "out").string()),
                       "robot.yaml", key);
  };
  check("slamm:\n  orb_features: 500\n", "'slamm' is not a known section (line 3");
  check("slam:\n  orb_features: 500\n  orb_features: 600\n", "slam.orb_features is given twice (again at line 5");
  check("slam:\n  orb_features: many\n", "slam.orb_features is not a valid value: 'many' is not a whole number (line 4");
  check("output:\n  wheel_propagation: maybe\n", "output.wheel_propagation is not a valid value (line 4");
  check("output:\n  pose_rate_hz: 5000\n", "output.pose_rate_hz = 5000 is outside");
}

// A copy of `base` whose calibration gives no mounting for the colour camera.
fs::path without_rgb_mounting(const fs::path& base, const std::string& name) {
  const fs::path copy = base.parent_path() / name;
  fs::copy(base, copy, fs::copy_options::recursive);
  std::string text = slurp(copy / "calibration.yaml");
  const auto from = text.find("    T_base_cam:");
  const auto rotation = text.find("rotation_xyzw", from);
  EXPECT_TRUE(from != std::string::npos && rotation != std::string::npos) << text;
  if (from != std::string::npos && rotation != std::string::npos) text.erase(from, text.find('\n', rotation) + 1 - from);
  std::ofstream(copy / "calibration.yaml", std::ios::trunc) << text;
  return copy;
}

TEST_F(CliConfig, RunRefusesAnUnknownCameraMountingAndPrintsTheOneItUses) {
  const fs::path& dir = dir_;
  simulate_base(dir);
  without_rgb_mounting(dir / "base", "no_mount");
  const auto run_with = [&](const std::string& camera) {
    std::ofstream(dir / "robot.yaml", std::ios::trunc) << "camera: {" << camera << "}\ncan: {interface: vcan0}\n";
    return run("run --config " + (dir / "robot.yaml").string() + " --out " + (dir / "out").string());
  };
  // No T_base_cam and no explicit identity: refused before any device or bus is used.
  const auto refused = run_with("source: 'replay:no_mount'");
  expect_input_error(refused, "robot.yaml", "the camera mounting is unknown");
  EXPECT_NE(refused.output.find("cameras.rgb.T_base_cam"), std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find("camera.mounting: identity"), std::string::npos) << refused.output;
  EXPECT_EQ(refused.output.find("camera mounting T_base_cam"), std::string::npos) << refused.output;
  // Both a configured and a calibrated mounting: which one was meant is unknown.
  expect_input_error(run_with("source: 'replay:base', mounting: identity"), "robot.yaml", "keep one");
  // The mounting used is printed, wherever it came from (the run may then stop at the bus, which
  // this machine may not have).
  const auto identity = run_with("source: 'replay:no_mount', mounting: identity");
  EXPECT_NE(identity.output.find("camera mounting T_base_cam (camera.mounting): translation [0.000, 0.000, 0.000] m, "
                                 "roll pitch yaw [0.0, 0.0, 0.0] deg; trajectory and map in the base frame"),
            std::string::npos)
      << identity.output;
  const auto configured =
      run_with("source: 'replay:no_mount', mounting: {translation: [0.1, 0, 0.3], rotation_xyzw: [-0.5, 0.5, -0.5, 0.5]}");
  EXPECT_NE(configured.output.find("camera mounting T_base_cam (camera.mounting): translation [0.100, 0.000, 0.300] m, "
                                   "roll pitch yaw [-90.0, 0.0, -90.0] deg"),
            std::string::npos)
      << configured.output;
  const auto calibrated = run_with("source: 'replay:base'");
  EXPECT_NE(calibrated.output.find("calibration.yaml): translation [0.150, 0.000, 0.500] m, "
                                   "roll pitch yaw [-90.0, 0.0, -90.0] deg"),
            std::string::npos)
      << calibrated.output;
  // A mistyped mounting names the key and its line.
  expect_input_error(run_with("source: 'replay:base', mounting: optical"), "robot.yaml",
                     "camera.mounting must be identity or {translation");
  expect_input_error(run_with("source: 'replay:base', mounting: {translation: [0, 0, 0], rotation_xyzw: [1, 1, 0, 0]}"),
                     "robot.yaml", "camera.mounting.rotation_xyzw is not a unit quaternion");
}

TEST_F(CliConfig, ReplayWritesTheBaseFrameOnlyWithAKnownMounting) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  const fs::path unknown = without_rgb_mounting(base, "no_mount");
  const auto refused = replay(unknown, dir / "out", "--frame base");
  EXPECT_EQ(refused.exit_code, 2) << refused.output;
  EXPECT_NE(refused.output.find("--frame base needs the camera mounting"), std::string::npos) << refused.output;
  ASSERT_EQ(replay(unknown, dir / "out").exit_code, 0);
  EXPECT_NE(slurp(dir / "out" / "report.json").find("\"output_frame\": \"camera\""), std::string::npos);
  ASSERT_EQ(replay(base, dir / "out").exit_code, 0);
  EXPECT_NE(slurp(dir / "out" / "report.json").find("\"output_frame\": \"base\""), std::string::npos);
}

TEST_F(CliConfig, DeeplyNestedYamlIsNamedAsInvalidYaml) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  const std::string deep = "x: " + std::string(5000, '[') + std::string(5000, ']') + "\n";
  std::ofstream(dir / "deep.yaml") << "slam:\n  orb_features: 500\n" << deep;
  expect_input_error(replay(base, dir / "out", "--config " + (dir / "deep.yaml").string()), "deep.yaml",
                     "not valid YAML (nested too deep)");
  const fs::path recording = with_calibration_edit(base, "deep", "depth_scale:", deep + "depth_scale:");
  expect_input_error(replay(recording, dir / "out"), "calibration.yaml", "not valid YAML (nested too deep)");
}

TEST_F(CliConfig, RunRejectsANonFiniteSlamValueByFileAndKey) {
  const fs::path& dir = dir_;
  std::ofstream(dir / "robot.yaml") << "camera: {source: 'replay:rec'}\ncan: {interface: vcan0}\n"
                                       "slam:\n  max_depth_m: .nan\n";
  expect_input_error(run("run --config " + (dir / "robot.yaml").string() + " --out " + (dir / "out").string()),
                     "robot.yaml", "slam.max_depth_m");
  std::ofstream(dir / "robot.yaml", std::ios::trunc) << "camera: {source: 'replay:rec', exit_after_end_s: .nan}\n";
  expect_input_error(run("run --config " + (dir / "robot.yaml").string() + " --out " + (dir / "out").string()),
                     "robot.yaml", "camera.exit_after_end_s");
}

TEST_F(CliConfig, ImplausibleCalibrationNumbersAreRejectedByFileAndKey) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  struct Case {
    const char* name;
    const char* from;
    const char* to;
    const char* key;
  };
  for (const Case& c : {
           Case{"inf_fx", "intrinsics: [517.3", "intrinsics: [.inf", "cameras.rgb.intrinsics[0]"},
           Case{"nan_cxcy", "318.6, 255.3", ".nan, .nan", "cameras.rgb.intrinsics[2]"},
           Case{"far_cx", "318.6, 255.3", "5000, 255.3", "cameras.rgb.intrinsics[2] (cx)"},
           Case{"nan_distortion", "distortion: [0.0, ", "distortion: [.nan, ", "cameras.rgb.distortion[0]"},
           Case{"huge_distortion", "distortion: [0.0, ", "distortion: [1e9, ", "cameras.rgb.distortion[0]"},
           Case{"huge_fx", "intrinsics: [517.3, 516.5", "intrinsics: [1e300, 1e300", "cameras.rgb.intrinsics[0] (fx)"},
           Case{"tiny_fx", "intrinsics: [517.3, 516.5", "intrinsics: [1e-9, 1e-9", "cameras.rgb.intrinsics[0] (fx)"},
           Case{"inf_depth_scale", "depth_scale: 5000.0", "depth_scale: .inf", "depth_scale"},
           Case{"tiny_depth_scale", "depth_scale: 5000.0", "depth_scale: 1e-12", "depth_scale"},
           Case{"nan_rotation", "rotation_xyzw: [-0.5, 0.5, -0.5, 0.5]", "rotation_xyzw: [.nan, .nan, .nan, .nan]",
                "cameras.rgb.T_base_cam.rotation_xyzw"},
           Case{"nan_translation", "translation: [0.15,", "translation: [.nan,", "cameras.rgb.T_base_cam.translation[0]"},
           Case{"nan_wheel_radius", "radius_m: 0.05", "radius_m: .nan", "wheels.radius_m"},
           Case{"nan_fov", "field_of_view_deg: 190.0", "field_of_view_deg: .nan", "cameras.fisheye.field_of_view_deg"},
       }) {
    SCOPED_TRACE(c.name);
    const fs::path recording = with_calibration_edit(base, c.name, c.from, c.to);
    expect_input_error(replay(recording, dir / "out"), (recording / "calibration.yaml").string(), c.key);
  }
}

TEST_F(CliConfig, MisspeltCalibrationKeysAreRejectedByKeyPath) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  struct Case {
    const char* name;
    const char* from;
    const char* to;
    const char* key;
  };
  for (const Case& c : {
           Case{"depth_scael", "depth_scale:", "depth_scael:", "'depth_scael' is not a known key"},
           Case{"distortoin", "distortion:", "distortoin:", "cameras.rgb.distortoin is not a known key"},
           Case{"camera_name", "  fisheye:", "  fishey:", "cameras.fishey is not a known key"},
           Case{"pose_key", "translation:", "translatoin:", "cameras.rgb.T_base_cam.translatoin is not a known key"},
           Case{"wheel_key", "track_width_m:", "trackwidth_m:", "wheels.trackwidth_m is not a known key"},
       }) {
    SCOPED_TRACE(c.name);
    const fs::path recording = with_calibration_edit(base, c.name, c.from, c.to);
    expect_input_error(replay(recording, dir / "out"), (recording / "calibration.yaml").string(), c.key);
  }
}

TEST_F(CliConfig, CalibrationNodesOfTheWrongTypeAreRejectedByKeyPath) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  const std::string camera = "cameras:\n  rgb:\n    model: pinhole\n    width: 640\n    height: 480\n";
  const std::string intrinsics = "    intrinsics: [517.3, 516.5, 318.6, 255.3]\n";
  struct Case {
    const char* name;
    std::string text;
    const char* key;
  };
  for (const Case& c : {
           Case{"top_level_list", "- 1\n- 2\n", "expected a map at the top level"},
           Case{"scalar_cameras", "depth_scale: 5000.0\ncameras: 5\n", "'cameras' must be a map"},
           Case{"scalar_camera", "cameras:\n  rgb: 5\n", "'cameras.rgb' must be a map"},
           Case{"list_pose", camera + intrinsics + "    T_base_cam: [1, 2]\n", "'cameras.rgb.T_base_cam' must be a map"},
           Case{"scalar_wheels", camera + intrinsics + "wheels: 1\n", "'wheels' must be a map"},
           Case{"list_width", "cameras:\n  rgb:\n    model: pinhole\n    width: [640]\n", "cameras.rgb.width is not a valid value"},
           Case{"complex_key", camera + intrinsics + "? [a, b]\n: 1\n", "the key at line 7"},
           Case{"duplicate_key", "depth_scale: 1000\n" + camera + intrinsics + "depth_scale: 5000\n",
                "depth_scale is given twice"},
       }) {
    SCOPED_TRACE(c.name);
    const fs::path recording = dir / c.name;
    fs::copy(base, recording, fs::copy_options::recursive);
    std::ofstream(recording / "calibration.yaml", std::ios::trunc) << c.text;
    expect_input_error(replay(recording, dir / "out"), (recording / "calibration.yaml").string(), c.key);
  }
  // As reported: a scalar beside its former children, and a complex key appended to the file.
  expect_input_error(replay(with_calibration_edit(base, "reported_scalar", "cameras:", "cameras: 5\nxcameras:"),
                            dir / "out"),
                     "calibration.yaml", "cameras");
  expect_input_error(replay(with_calibration_edit(base, "reported_complex", "wheels:", "? [a, b]\n: 1\nwheels:"),
                            dir / "out"),
                     "calibration.yaml", "is not a plain name");
}

TEST_F(CliConfig, ValidFilesStillReplayAndTheReportIsJson) {
  const fs::path& dir = dir_;
  const fs::path base = simulate_base(dir);
  const fs::path config = fs::path(RANKSLAM_SOURCE_DIR) / "deploy/config/default.yaml";
  const auto result = replay(base, dir / "out", "--config " + config.string());
  ASSERT_EQ(result.exit_code, 0) << result.output;
  const std::string report = slurp(dir / "out" / "report.json");
  EXPECT_FALSE(std::regex_search(report, std::regex(R"(:\s*-?(nan|inf))", std::regex::icase))) << report;
}

}  // namespace
