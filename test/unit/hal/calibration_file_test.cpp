#include "rankslam/record/recording_writer.hpp"
#include "rankslam/replay/calibration_file.hpp"
#include "rankslam/replay/recording.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace rankslam::replay {
namespace {

namespace fs = std::filesystem;

class CalibrationFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("calibration_file_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // Loads `text` as dir_/calibration.yaml; the error, or empty.
  std::string load(const std::string& text) {
    std::ofstream(dir_ / "calibration.yaml", std::ios::trunc) << text;
    return load_calibration_yaml(dir_ / "calibration.yaml", calibration_);
  }

  fs::path dir_;
  hal::Calibration calibration_;
};

// The simulator's corridor-loop calibration: both cameras, the fisheye's field of view, wheels.
const std::string kValid = R"(# rankslam recording calibration: simulated scene 'corridor-loop'
depth_scale: 5000.0  # raw depth units per metre
depth_noise_per_m: 0.001425  # a in the axial depth noise a*z^2
cameras:
  rgb:  # colour camera; depth and IR images are registered to it
    model: pinhole
    width: 640
    height: 480
    intrinsics: [517.3, 516.5, 318.6, 255.3]  # fx fy cx cy
    distortion: [0.0, 0.0, 0.0, 0.0, 0.0]  # k1 k2 p1 p2 k3
    T_base_cam:  # camera optical frame (x right, y down, z forward) -> base (x forward, y left, z up)
      translation: [0.15, 0.0, 0.5]
      rotation_xyzw: [-0.5, 0.5, -0.5, 0.5]
  fisheye:  # wide-angle camera, equidistant model
    model: fisheye
    width: 960
    height: 600
    intrinsics: [230.0, 230.0, 479.5, 299.5]  # fx fy cx cy
    distortion: [0.0129, 0.00266, -0.00587, 0.00126]  # k1 k2 k3 k4 (OpenCV fisheye)
    T_base_cam:  # camera optical frame (x right, y down, z forward) -> base (x forward, y left, z up)
      translation: [0.1, 0.02, 0.75]
      rotation_xyzw: [-0.47192937092440085, 0.45573689600345785, -0.5242653271673446, 0.542892638751116]
    field_of_view_deg: 190.0  # image circle: 95 deg from the optical axis
wheels:  # differential drive, encoder frames in can.log
  radius_m: 0.05
  track_width_m: 0.3
  ticks_per_revolution: 4096
  can_id: 0x101
)";

// kValid with the first `from` replaced by `to`.
std::string edited(const std::string& from, const std::string& to) {
  std::string text = kValid;
  const auto at = text.find(from);
  if (at == std::string::npos) ADD_FAILURE() << from << " is not in the valid calibration";
  return at == std::string::npos ? text : text.replace(at, from.size(), to);
}

TEST_F(CalibrationFileTest, WhatTheSimulatorAndTheRecorderWriteLoads) {
  ASSERT_EQ(load(kValid), "");
  EXPECT_DOUBLE_EQ(calibration_.rgb.fx, 517.3);
  ASSERT_TRUE(calibration_.fisheye.has_value());
  EXPECT_DOUBLE_EQ(calibration_.fisheye->field_of_view_deg, 190.0);
  EXPECT_DOUBLE_EQ(calibration_.rgb.field_of_view_deg, 0.0) << "not given";
  ASSERT_TRUE(calibration_.wheels.has_value());
  EXPECT_EQ(calibration_.wheels->can_id, 0x101U);

  // The recorder's writer, on every published TUM calibration and on one with every section.
  for (const char* camera : {"freiburg1", "freiburg2", "freiburg3"}) {
    const hal::Calibration tum = *tum_calibration(camera);
    ASSERT_EQ(load(record::calibration_yaml(tum, camera)), "") << camera;
    EXPECT_DOUBLE_EQ(calibration_.rgb.distortion[4], tum.rgb.distortion[4]) << camera;
  }
  ASSERT_EQ(load(kValid), "");
  const hal::Calibration full = calibration_;
  ASSERT_EQ(load(record::calibration_yaml(full, "every section")), "");
  ASSERT_TRUE(calibration_.fisheye.has_value());
  EXPECT_DOUBLE_EQ(calibration_.fisheye->field_of_view_deg, 190.0);
  EXPECT_TRUE(calibration_.wheels.has_value());
  EXPECT_TRUE(calibration_.rgb.T_base_cam.isApprox(full.rgb.T_base_cam, 1e-9));
}

TEST_F(CalibrationFileTest, EveryNumberMustBeFiniteAndPlausible) {
  struct Case {
    const char* from;
    const char* to;
    const char* key;
  };
  for (const Case& c : {
           Case{"intrinsics: [517.3", "intrinsics: [.inf", "cameras.rgb.intrinsics[0]"},
           Case{"516.5, 318.6", "516.5, .nan", "cameras.rgb.intrinsics[2]"},
           Case{"318.6, 255.3", "318.6, .nan", "cameras.rgb.intrinsics[3]"},
           Case{"intrinsics: [517.3", "intrinsics: [1e300", "cameras.rgb.intrinsics[0] (fx) = 1e+300 is outside 32 .. 64000"},
           Case{"intrinsics: [517.3", "intrinsics: [1e-9", "cameras.rgb.intrinsics[0] (fx)"},
           Case{"517.3, 516.5", "517.3, 20", "cameras.rgb.intrinsics[1] (fy)"},
           Case{"516.5, 318.6", "516.5, -700", "cameras.rgb.intrinsics[2] (cx)"},
           Case{"318.6, 255.3", "318.6, 1000", "cameras.rgb.intrinsics[3] (cy)"},
           Case{"distortion: [0.0, ", "distortion: [.nan, ", "cameras.rgb.distortion[0]"},
           Case{"0.0, 0.0, 0.0]  # k1", "0.0, 0.0, 1e6]  # k1", "cameras.rgb.distortion[4]"},
           Case{"0.00126]", "-.inf]", "cameras.fisheye.distortion[3]"},
           Case{"depth_scale: 5000.0", "depth_scale: .inf", "depth_scale = inf is not a finite number"},
           Case{"depth_scale: 5000.0", "depth_scale: 0.5", "depth_scale"},
           Case{"depth_scale: 5000.0", "depth_scale: 1e7", "depth_scale"},
           Case{"depth_noise_per_m: 0.001425", "depth_noise_per_m: .nan", "depth_noise_per_m"},
           Case{"rotation_xyzw: [-0.5, 0.5, -0.5, 0.5]", "rotation_xyzw: [.nan, .nan, .nan, .nan]",
                "cameras.rgb.T_base_cam.rotation_xyzw[0]"},
           Case{"rotation_xyzw: [-0.5, 0.5, -0.5, 0.5]", "rotation_xyzw: [-0.5, 0.5, -0.5, 0.6]",
                "cameras.rgb.T_base_cam.rotation_xyzw is not a unit quaternion"},
           Case{"translation: [0.15, 0.0, 0.5]", "translation: [0.15, .nan, 0.5]", "cameras.rgb.T_base_cam.translation[1]"},
           Case{"translation: [0.15, 0.0, 0.5]", "translation: [150, 0.0, 500]", "cameras.rgb.T_base_cam.translation[0]"},
           Case{"width: 640", "width: 0", "cameras.rgb.width"},
           Case{"field_of_view_deg: 190.0", "field_of_view_deg: .inf", "cameras.fisheye.field_of_view_deg"},
           Case{"radius_m: 0.05", "radius_m: .nan", "wheels.radius_m"},
           Case{"track_width_m: 0.3", "track_width_m: .inf", "wheels.track_width_m"},
           Case{"ticks_per_revolution: 4096", "ticks_per_revolution: 0", "wheels.ticks_per_revolution"},
           Case{"can_id: 0x101", "can_id: 0x800", "wheels.can_id"},
       }) {
    const std::string error = load(edited(c.from, c.to));
    EXPECT_NE(error.find(c.key), std::string::npos) << c.to << ": " << error;
    EXPECT_NE(error.find("calibration.yaml: "), std::string::npos) << c.to << ": " << error;
  }
}

TEST_F(CalibrationFileTest, UnknownKeysAtAnyLevelAreNamedByPath) {
  EXPECT_NE(load(edited("depth_scale:", "depth_scael:")).find("'depth_scael' is not a known key"), std::string::npos);
  EXPECT_NE(load(edited("distortion:", "distortoin:")).find("cameras.rgb.distortoin is not a known key"),
            std::string::npos);
  EXPECT_NE(load(edited("  fisheye:", "  ir:")).find("cameras.ir is not a known key"), std::string::npos);
  EXPECT_NE(load(edited("      translation:", "      position:")).find("cameras.rgb.T_base_cam.position"),
            std::string::npos);
  EXPECT_NE(load(edited("  can_id:", "  can_idx:")).find("wheels.can_idx is not a known key"), std::string::npos);
}

TEST_F(CalibrationFileTest, NodesOfTheWrongTypeAndOddKeysAreErrorsNotExceptions) {
  const std::string camera = "cameras:\n  rgb:\n    model: pinhole\n    width: 640\n    height: 480\n"
                             "    intrinsics: [517.3, 516.5, 318.6, 255.3]\n";
  struct Case {
    std::string text;
    const char* message;
  };
  for (const Case& c : {
           Case{"cameras: 5\n", "'cameras' must be a map"},
           Case{"cameras: [rgb]\n", "'cameras' must be a map"},
           Case{"cameras:\n  rgb: pinhole\n", "'cameras.rgb' must be a map"},
           Case{camera + "    T_base_cam: 0\n", "'cameras.rgb.T_base_cam' must be a map"},
           Case{camera + "    distortion: 0\n", "cameras.rgb.distortion must be a list"},
           Case{camera + "wheels: [1]\n", "'wheels' must be a map"},
           Case{camera + "depth_scale: {a: 1}\n", "depth_scale is not a valid value"},
           Case{"- cameras\n", "expected a map at the top level"},
           Case{"cameras: 5\nxcameras:\n  rgb: {}\n", "xcameras"},
           Case{camera + "? [a, b]\n: 1\n", "the key at line 7, column 3 is not a plain name"},
           Case{"cameras:\n  rgb:\n    ? {model: pinhole}\n    : 1\n", "cameras.rgb: the key at line 3"},
           Case{camera + "depth_scale: 1000\ndepth_scale: 5000\n", "depth_scale is given twice"},
           Case{camera + "    width: 320\n", "cameras.rgb.width is given twice"},
           Case{"x: " + std::string(5000, '[') + std::string(5000, ']') + "\n" + camera, "not valid YAML (nested too deep)"},
           Case{"x: " + std::string(100, '[') + std::string(100, ']') + "\n" + camera, "nested too deep"},
           Case{camera + "    intrinsics: [1, 2\n", "not valid YAML"},
       }) {
    std::string error;
    EXPECT_NO_THROW(error = load(c.text)) << c.text;
    EXPECT_NE(error.find(c.message), std::string::npos) << c.text << "\n" << error;
    EXPECT_EQ(error.rfind((dir_ / "calibration.yaml").string() + ": ", 0), 0U) << error;
  }
}

TEST_F(CalibrationFileTest, OnlyARegularFileIsRead) {
  EXPECT_NE(load_calibration_yaml(dir_, calibration_).find("not a regular file"), std::string::npos);
  EXPECT_NE(load_calibration_yaml(dir_ / "absent.yaml", calibration_).find("absent.yaml"), std::string::npos);
}

}  // namespace
}  // namespace rankslam::replay
