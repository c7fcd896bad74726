#pragma once

#include "rankslam/nav/pose_broadcaster.hpp"

#include <Eigen/Geometry>

#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>

namespace rankslam::app {

/// Where the RGB-D frames come from.
enum class CameraSource {
  kReplay,   ///< A recording directory played through the replay driver.
  kOpenNI2,  ///< An OpenNI2 device (first one, or a URI).
};

/// The robot configuration `rankslam run --config` reads (deploy/config/example-robot.yaml):
/// which drivers to build and how the output behaves. The `slam:` section of the same file is
/// read by load_slam_config.
struct RobotConfig {
  /// camera.source "replay:<dir>" or "openni2:[uri]".
  CameraSource camera_source = CameraSource::kReplay;
  /// Recording directory (replay; relative paths are taken from the YAML file's directory) or
  /// device URI (OpenNI2; empty = first device).
  std::string camera_location;
  /// camera.calibration: calibration.yaml for the OpenNI2 camera (relative to the YAML file);
  /// empty = intrinsics from the device's field of view.
  std::filesystem::path camera_calibration;
  /// camera.mounting: the camera's T_base_cam (optical frame → base), `identity` or a pose as
  /// calibration.yaml writes one; nullopt (absent): the calibration must give cameras.rgb.T_base_cam.
  std::optional<Eigen::Isometry3d> camera_mounting;
  /// camera.width/height/fps: OpenNI2 video mode; camera.ir: also stream IR.
  int camera_width = 640;
  int camera_height = 480;
  int camera_fps = 30;
  bool camera_ir = false;
  /// wide_camera.device: V4L2 node of the wide-angle camera (/dev/videoN); empty = none, and a
  /// replay source plays its recording's wide-angle images. Its calibration is camera.calibration's
  /// cameras.fisheye.
  std::string wide_device;
  /// wide_camera.width/height/fps: the V4L2 mode; wide_camera.format: auto, yuyv or mjpeg.
  int wide_width = 640;
  int wide_height = 480;
  int wide_fps = 30;
  std::string wide_format = "auto";
  /// camera.replay_rate: multiple of the recorded frame rate; 0 = lossless, as fast as the loop runs.
  double replay_rate = 1.0;
  /// camera.max_frames: replay at most this many frames, 0 = all.
  std::uint32_t max_frames = 0;
  /// camera.exit_after_end_s: after the recording ends keep the output running (the watchdog
  /// reports LOST) for this long, then stop as on SIGTERM; negative = until a signal.
  double exit_after_end_s = 2.0;
  /// can.interface: SocketCAN interface for pose output and wheel input (can0, vcan0, ...).
  std::string can_interface = "can0";
  /// can.interface was given in the file (rankslam record logs the bus only then).
  bool can_interface_given = false;
  /// can.play_wheel_frames: replay only; play the recording's can.log onto the bus on its
  /// recorded timing, as the base controller would send it.
  bool play_wheel_frames = true;
  /// output.*: pose and heartbeat rates, watchdog.
  nav::PoseOutputConfig output;
  /// output.dir: where trajectory.txt, map.ply and report.json are flushed on exit (--out wins).
  std::filesystem::path output_dir;
  /// output.max_trajectory_poses: capacity of the trajectory kept for the flush, reserved at start.
  std::uint32_t max_trajectory_poses = 100000;
  /// output.realtime_priority: SCHED_FIFO priority of the pose output's thread, so a loaded CPU
  /// does not delay the pose cycles; 0 = ordinary scheduling.
  int output_realtime_priority = 10;
  /// output.status_interval_s: a status line on stderr (the journal) this often while `run`
  /// works; 0 = none.
  double status_interval_s = 60.0;
  /// map.file: the map `run` starts in when the file exists (as with --load-map) and saves at
  /// every checkpoint and at exit (as with --save-map); empty = none. Relative to the YAML file.
  std::filesystem::path map_file;
  /// map.checkpoint_s: the map file and the outputs (trajectory, point map, report) are written
  /// this often, off the loop's thread; 0 = only at exit.
  double checkpoint_s = 30.0;
};

/// The top-level sections load_robot_config reads (robot, camera, wide_camera, can, output, map); the file's
/// `slam:`, `geometry:` and `wheel_odometry:` are load_pipeline_config's.
[[nodiscard]] const std::set<std::string>& robot_config_sections();

/// Reads every section but `slam:`; unknown sections and keys, keys given twice, and values that
/// are not valid (numbers: finite, within range) are errors naming the file and the key. Empty
/// string on success.
[[nodiscard]] std::string load_robot_config(const std::filesystem::path& path, RobotConfig& config);

/// Effective values, one "name = value  # doc" line each.
[[nodiscard]] std::string describe_robot_config(const RobotConfig& config);

}  // namespace rankslam::app

namespace rankslam::openni2 {
struct OpenNI2Options;
}
namespace rankslam::v4l2 {
struct V4l2Options;
}
namespace rankslam::hal {
class Camera;
struct Calibration;
}
namespace rankslam::replay {
struct Recording;
struct ReplayOptions;
class ReplayImageCamera;
}

namespace rankslam::app {

/// OpenNI2 driver options for a robot configuration with camera.source openni2: (reads
/// camera.calibration when given). Empty string on success, else the error naming the file.
[[nodiscard]] std::string openni2_options_from(const RobotConfig& config, openni2::OpenNI2Options& options);

/// V4L2 driver options for the robot configuration's wide_camera.
[[nodiscard]] v4l2::V4l2Options v4l2_options_from(const RobotConfig& config);

/// A recording's wide-angle images as a camera, built but not opened, paced as `replay_options`
/// say but all of them and decoded ahead; null when it has none or no calibration for them.
[[nodiscard]] std::unique_ptr<replay::ReplayImageCamera> make_replay_wide_camera(
    const replay::Recording& recording, const replay::ReplayOptions& replay_options);

/// The wide-angle camera a robot configuration names, built but not opened, into `camera`:
/// wide_camera.device over V4L2 (with a live RGB-D camera: the stamps of both are CLOCK_MONOTONIC),
/// whose calibration (`calibration`'s cameras.fisheye) must have the configured size; else the recorded wide-angle images of a replay source (`recording`, null
/// for a live camera), paced by `replay_options`; else none (`camera` empty). `description`
/// names it. Empty on success, else the error naming the configuration key.
[[nodiscard]] std::string make_wide_camera(const RobotConfig& config, const hal::Calibration& calibration,
                                           const replay::Recording* recording, const replay::ReplayOptions& replay_options,
                                           std::unique_ptr<hal::Camera>& camera, std::string& description);

}  // namespace rankslam::app
