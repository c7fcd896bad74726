#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/interfaces.hpp"
#include "rankslam/nav/live_wheels.hpp"
#include "rankslam/nav/pose_broadcaster.hpp"

#include <Eigen/Geometry>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <optional>

namespace rankslam::nav {

/// What the SLAM thread hands to the pose output: the latest sample and the camera state.
/// Thread-safe; never allocates.
class PoseMailbox {
 public:
  /// A processed camera frame. `map_correction`: the pose-graph correction it applied (base
  /// frames), or null. `wheel_stamp_ns`: its stamp on the wheel odometry's clock, none without wheels.
  void post(const PoseSample& sample, const Eigen::Isometry3d* map_correction, std::optional<std::int64_t> wheel_stamp_ns);
  void set_camera_fault(bool fault);
  void set_end_of_stream();
  /// The wide-angle camera faulted or went silent (true), or delivers again (false).
  void set_wide_camera_fault(bool fault);

  /// The output's side: hands the newest sample to `broadcaster` when there is one it has not
  /// seen (with the corrections of every sample since), and the camera state. The sample's wheel
  /// stamp goes to `wheel_stamp_ns` with it.
  void deliver(PoseBroadcaster& broadcaster, std::optional<std::int64_t>& wheel_stamp_ns);

 private:
  std::mutex mutex_;
  std::optional<PoseSample> sample_;
  /// Corrections of the samples since the output last took one: a sample overwritten before the
  /// output sees it must not take its correction with it.
  Eigen::Isometry3d pending_correction_ = Eigen::Isometry3d::Identity();
  std::optional<std::int64_t> wheel_stamp_ns_;
  std::uint64_t sample_count_ = 0;
  std::uint64_t delivered_count_ = 0;
  bool camera_fault_ = false;
  bool end_of_stream_ = false;
  bool wide_camera_fault_ = false;
};

/// How the pose output runs; fixed after construction.
struct PoseOutputOptions {
  PoseOutputConfig broadcast;  ///< rates, watchdog, wheel propagation
  /// The wheels' noise, which the sent sigmas grow by while the wheels carry the pose on.
  WheelNoise wheel_noise;
  /// Identifier of the wheel encoder frames it takes in (standard, 11 bit); others are ignored.
  std::uint32_t wheel_can_id = hal::WheelGeometry{}.can_id;
  /// Longest wait inside receive() between two due frames, so the mailbox is looked at often.
  std::chrono::milliseconds max_wait{20};
  /// Frames already queued on the bus taken in before the due frames are sent, at most.
  int max_queued_frames_per_step = 64;
};

/// Wheel frames the pose output received from its bus.
struct WheelInputCounters {
  std::uint64_t frames = 0;        ///< WheelTicks frames decoded
  std::uint64_t malformed = 0;     ///< the wheel identifier with a wrong length
  std::uint64_t counter_gaps = 0;  ///< rolling-counter jumps: frames lost somewhere
  std::uint64_t unmatched = 0;     ///< replay through the bus: frames that match no played frame
};

/// The pose output's thread: the latest SLAM pose out at its rates (PoseBroadcaster), moved on
/// by the wheels since its camera frame, and the wheel frames in from the same bus to the shared
/// odometry. It owns no bus; SLAM never waits for it. Never allocates.
class PoseOutput {
 public:
  PoseOutput(const PoseOutputOptions& options, hal::CanBus& bus, const hal::Clock& clock, PoseMailbox& mailbox,
             LiveWheels& wheels);

  /// Until `stop`: marks the wheels as receiving, then step() after step().
  void run(const std::atomic<bool>& stop);
  /// One cycle: the frames already queued on the bus taken in, the mailbox's news to the
  /// broadcaster, every due frame sent, then at most one frame received, waiting no longer than
  /// until the next due frame.
  void step();

  [[nodiscard]] const PoseOutputCounters& pose_counters() const { return broadcaster_.counters(); }
  [[nodiscard]] const WheelInputCounters& wheel_counters() const { return wheel_counters_; }

 private:
  void take_in(const hal::CanFrame& frame);

  PoseOutputOptions options_;
  hal::CanBus& bus_;
  const hal::Clock& clock_;
  PoseMailbox& mailbox_;
  LiveWheels& wheels_;
  PoseBroadcaster broadcaster_;
  std::optional<std::int64_t> sample_wheel_stamp_ns_;
  std::optional<std::uint8_t> last_counter_;
  WheelInputCounters wheel_counters_;
};

}  // namespace rankslam::nav
