// Builds the OpenNI2 and V4L2 drivers' options from a robot configuration.
#include "robot_config.hpp"

#include "rankslam/openni2/openni2_camera.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/v4l2/v4l2_camera.hpp"

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

v4l2::V4l2Options v4l2_options_from(const RobotConfig& config) {
  v4l2::V4l2Options options;
  options.device = config.wide_device;
  options.width = config.wide_width;
  options.height = config.wide_height;
  options.fps = static_cast<std::uint32_t>(config.wide_fps);
  options.format = config.wide_format == "yuyv"    ? v4l2::PixelFormat::kYuyv
                   : config.wide_format == "mjpeg" ? v4l2::PixelFormat::kMjpeg
                                                   : v4l2::PixelFormat::kAuto;
  return options;
}

std::unique_ptr<replay::ReplayImageCamera> make_replay_wide_camera(const replay::Recording& recording,
                                                                   const replay::ReplayOptions& replay_options) {
  if (recording.fisheye.empty() || !recording.calibration.fisheye) return nullptr;
  replay::ReplayOptions options = replay_options;
  options.max_frames = 0;  // taken by stamp: the colour frames' end is the end
  options.load_ir = false;
  // Decoded while the loop works: waiting for each image would add its decoding to the replay.
  options.decode_ahead = true;
  return std::make_unique<replay::ReplayImageCamera>(recording, options);
}

std::string make_wide_camera(const RobotConfig& config, const hal::Calibration& calibration,
                             const replay::Recording* recording, const replay::ReplayOptions& replay_options,
                             std::unique_ptr<hal::Camera>& camera, std::string& description) {
  camera.reset();
  description.clear();
  if (!config.wide_device.empty()) {
    if (recording != nullptr) {
      return "wide_camera.device with camera.source replay: a live camera's stamps and the recording's have no "
             "clock in common; use an openni2: camera, or no wide_camera.device to play the recording's images";
    }
    if (!calibration.fisheye) {
      return "wide_camera.device needs cameras.fisheye in the calibration (" + calibration.source + ")";
    }
    if (calibration.fisheye->width != config.wide_width || calibration.fisheye->height != config.wide_height) {
      return "wide_camera is " + std::to_string(config.wide_width) + "x" + std::to_string(config.wide_height) +
             " but cameras.fisheye in " + calibration.source + " is " + std::to_string(calibration.fisheye->width) + "x" +
             std::to_string(calibration.fisheye->height);
    }
    camera = std::make_unique<v4l2::V4l2Camera>(v4l2_options_from(config));
    description = "v4l2:" + config.wide_device;
  } else if (recording != nullptr) {
    camera = make_replay_wide_camera(*recording, replay_options);
    if (camera) description = "replay of " + std::to_string(recording->fisheye.size()) + " wide-angle images";
  }
  return {};
}

}  // namespace rankslam::app
