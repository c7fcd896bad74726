#pragma once

#include "checkpointer.hpp"
#include "frame_pipeline.hpp"
#include "status_line.hpp"

#include "rankslam/hal/interfaces.hpp"
#include "rankslam/hal/nearest_image.hpp"
#include "rankslam/nav/pose_output.hpp"

#include <Eigen/Geometry>

#include <functional>

namespace rankslam::replay {
class ReplayDepthCamera;
class ReplayStream;
}
namespace rankslam::systemd {
class ServiceNotifier;
}

namespace rankslam::app {

/// The parts the loop of `rankslam run` connects, built and opened by the command.
struct LiveLoopParts {
  hal::DepthCamera* camera = nullptr;
  /// The same camera when it replays a recording (its warnings are printed), else null.
  replay::ReplayDepthCamera* replay_camera = nullptr;
  FramePipeline* pipeline = nullptr;
  nav::PoseMailbox* mailbox = nullptr;
  /// The wheel odometry is the prior: each pose sample carries its frame's wheel stamp.
  bool wheels = false;
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  /// After a recording's end: stop after this long; negative: only when asked to.
  double exit_after_end_s = 2.0;
  /// Camera read timeout; the loop goes round at least this often while the camera is silent.
  std::chrono::milliseconds read_wait{100};
  /// Optional: the service manager (READY=1, WATCHDOG=1 per turn, STOPPING=1) and the journal.
  systemd::ServiceNotifier* notifier = nullptr;
  StatusLine* status_line = nullptr;
  /// Optional: offered every processed frame (map.checkpoint_s).
  Checkpointer* checkpointer = nullptr;
  /// Optional: the wide-angle camera's images, paired with each frame; each read waits at most
  /// `wide_wait` (0 for a live or paced camera). `wide_camera_open`: false when it failed to
  /// open, and the heartbeat says so for the whole run.
  hal::NearestImage* wide = nullptr;
  /// The same camera's replay, whose warnings are printed; else null.
  replay::ReplayStream* wide_replay = nullptr;
  std::chrono::milliseconds wide_wait{0};
  bool wide_camera_open = true;
  /// A failed read, or no wide-angle image for this long (output.watchdog_timeout_s), sets the
  /// heartbeat's WideCameraFault.
  std::int64_t wide_silence_ns = 500'000'000;
};

/// Camera → SLAM loop → pose mailbox until `stop()` returns true or the recording has ended
/// `exit_after_end_s` ago. Every turn feeds the notifier and the status line, whatever the camera
/// did; only a turn that does not come back (a stuck read or frame) starves the watchdog.
/// Returns true when stopped by `stop()`. Allocates nothing per frame beyond the pipeline.
bool run_live_loop(const LiveLoopParts& parts, const std::function<bool()>& stop);

}  // namespace rankslam::app
