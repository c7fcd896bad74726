// Builds the OpenNI2 driver's options from a robot configuration.
#include "robot_config.hpp"

#include "rankslam/openni2/openni2_camera.hpp"
#include "rankslam/replay/recording.hpp"

namespace rankslam::app {

std::string openni2_options_from(const RobotConfig& config, openni2::OpenNI2Options& options) {
  options = openni2::OpenNI2Options{};
  options.uri = config.camera_location;
  options.width = config.camera_width;
  options.height = config.camera_height;
  options.fps = config.camera_fps;
  options.ir = config.camera_ir;
  options.playback_speed = config.replay_rate;
  if (!config.camera_calibration.empty()) {
    hal::Calibration calibration;
    if (auto error = replay::load_calibration_yaml(config.camera_calibration, calibration); !error.empty()) return error;
    options.calibration = calibration;
  }
  return {};
}

}  // namespace rankslam::app
