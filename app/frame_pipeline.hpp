#pragma once

#include "wheel_player.hpp"

#include "rankslam/eval/json_writer.hpp"
#include "rankslam/eval/run_report.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/hal/interfaces.hpp"
#include "rankslam/nav/live_wheels.hpp"
#include "rankslam/nav/pose_uncertainty.hpp"
#include "rankslam/nav/wheel_prior.hpp"
#include "rankslam/replay/replay_can_bus.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <array>
#include <chrono>
#include <filesystem>
#include <cstdint>
#include <optional>
#include <vector>

namespace rankslam::app {

/// Where a camera frame's wheel prior comes from: the one difference in the wheels between a
/// replay and a run, which both feed the odometry from a hal::CanBus.
class WheelSource {
 public:
  virtual ~WheelSource() = default;
  /// The prior for the camera frame at `stamp_ns` (wheel clock) into `prior`; false without one.
  [[nodiscard]] virtual bool prior_for(std::int64_t stamp_ns, nav::MotionPrior& prior) = 0;
};

/// A recording's wheel frames through the replay bus, received as far as the camera frame:
/// deterministic, the same priors every time.
class ReplayedWheels final : public WheelSource {
 public:
  ReplayedWheels(replay::ReplayCanBus& bus, nav::WheelPrior& wheels) : bus_(bus), wheels_(wheels) {}
  [[nodiscard]] bool prior_for(std::int64_t stamp_ns, nav::MotionPrior& prior) override;

 private:
  replay::ReplayCanBus& bus_;
  nav::WheelPrior& wheels_;
};

/// Wheel frames the pose output thread receives from the robot's bus (nav::LiveWheels), waiting
/// for the one past the camera frame: a live base's up to three wheel periods while frames are
/// arriving at all; a recording's played onto the bus (`player`) for as long as it plays, since
/// a lossless replay camera may run ahead of the timing the wheel frames keep.
class ReceivedWheels final : public WheelSource {
 public:
  /// `player`: empty for a live base; may be started after construction.
  ReceivedWheels(nav::LiveWheels& wheels, const std::optional<WheelPlayer>& player) : wheels_(wheels), player_(player) {}
  [[nodiscard]] bool prior_for(std::int64_t stamp_ns, nav::MotionPrior& prior) override;

 private:
  nav::LiveWheels& wheels_;
  const std::optional<WheelPlayer>& player_;
};

/// How the pipeline runs and what it keeps; fixed at set-up, where every buffer is reserved.
struct PipelineOptions {
  /// Poses the trajectory keeps; later frames are counted as overflow.
  std::size_t max_frames = 0;
  /// Camera stamps are a recording's (frame.stamp_s, put on the wheel clock by
  /// nav::recording_stamp_ns); false: a live camera's CLOCK_MONOTONIC frame.stamp_ns.
  bool recording_clock = true;
  /// Wait for each pose-graph solve, so a replay gives the same result every time.
  bool synchronous_backend = false;
  /// Keep frames.csv records, timings, key-frame links and loop closures, and re-express the
  /// trajectory on the optimised key-frames at finish(); false: the trajectory is the poses as sent.
  bool frame_log = false;
  /// The wide-angle camera's place-recognition words (null: the built-in ones); must outlive set-up.
  const wide::Vocabulary* vocabulary = nullptr;
};

/// The per-frame path `replay` and `run` share: camera frame + wheel prior → SLAM loop → the
/// results collected for the outputs. The commands differ only in the sources they build.
class FramePipeline {
 public:
  FramePipeline(const slam::SlamConfig& config, const hal::Calibration& calibration, WheelSource* wheels,
                const PipelineOptions& options);

  /// The frame's stamp on the wheel odometry's clock.
  [[nodiscard]] std::int64_t wheel_stamp_ns(const hal::RgbdFrame& frame) const;
  /// One camera frame through the SLAM loop with its wheel prior and the wide-angle image paired
  /// with it (null: none); the result is collected.
  slam::FrameResult process(const hal::RgbdFrame& frame, const hal::ImageFrame* wide = nullptr);
  /// The last optimisation; with frame_log, every pose re-expressed on its optimised key-frame.
  void finish();

  [[nodiscard]] slam::SlamLoop& loop() { return loop_; }
  [[nodiscard]] const slam::SlamLoop& loop() const { return loop_; }
  /// Set-up: starts in the map saved in `path` (see slam::SlamLoop::load_map) and says so on
  /// stdout; kExitOk, or kExitInput after printing why the file was refused.
  [[nodiscard]] int load_map(const std::filesystem::path& path);
  /// The poses of the frames found in the map: without the frames whose status was kLost and
  /// those a relocalisation withdrew (slam::FrameResult::retracted_frames).
  [[nodiscard]] const eval::Trajectory& trajectory() const { return trajectory_; }
  /// Frames processed.
  [[nodiscard]] std::uint64_t frames() const { return frames_; }
  /// The relocalisations so far (the first kMaxRelocalisations).
  [[nodiscard]] const std::vector<eval::RelocalisationRecord>& relocalisations() const { return relocalisations_; }
  static constexpr std::size_t kMaxRelocalisations = 256;
  [[nodiscard]] std::uint64_t trajectory_overflow() const { return trajectory_overflow_; }
  [[nodiscard]] const eval::StatusCounts& status_counts() const { return status_counts_; }
  /// Frames neither registered nor first: the wheels carried them, or nothing did.
  [[nodiscard]] int failed_frames() const { return failed_frames_; }
  [[nodiscard]] bool wheels_used() const { return wheels_ != nullptr; }
  /// The base in the odom frame at the last processed frame (the base at the first frame; the
  /// map corrections do not move it) and its standard deviations, as PoseQuality sends them
  /// (none: unknown).
  [[nodiscard]] const Eigen::Isometry3d& T_odom_base() const { return T_odom_base_; }
  [[nodiscard]] const std::optional<nav::PoseSigmas>& sigmas() const { return sigmas_; }

  // With frame_log:
  [[nodiscard]] const std::vector<eval::FrameRecord>& frame_records() const { return frame_records_; }
  [[nodiscard]] const std::vector<double>& frame_ms() const { return frame_ms_; }
  [[nodiscard]] const std::array<std::vector<double>, slam::StageTimes::kCount>& stage_ms() const { return stage_ms_; }
  [[nodiscard]] const std::vector<slam::LoopClosure>& closures() const { return closures_; }
  /// The RGBD–mono edges of the wide-angle camera, as closures between their key-frames.
  [[nodiscard]] const std::vector<slam::LoopClosure>& wide_edges() const { return wide_edges_; }

 private:
  struct KeyframeLink {
    int node = -1;
    std::uint32_t generation = 0;
    Eigen::Isometry3d T_keyframe_cam = Eigen::Isometry3d::Identity();
  };

  /// With frame_log: the RGBD–mono edges the loop logged since the last call.
  void collect_wide_edges();

  PipelineOptions options_;
  Eigen::Isometry3d T_base_cam_;
  /// The map corrections applied so far (world frames): T_world_cam = T_world_odom·T_odom_cam.
  Eigen::Isometry3d T_world_odom_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_odom_base_ = Eigen::Isometry3d::Identity();
  std::optional<nav::PoseSigmas> sigmas_;
  slam::SlamLoop loop_;
  WheelSource* wheels_;
  nav::MotionPrior prior_;
  eval::Trajectory trajectory_;
  std::uint64_t trajectory_overflow_ = 0;
  std::uint64_t frames_ = 0;
  std::vector<eval::RelocalisationRecord> relocalisations_;
  eval::StatusCounts status_counts_;
  int failed_frames_ = 0;
  std::vector<eval::FrameRecord> frame_records_;
  std::vector<double> frame_ms_;
  std::array<std::vector<double>, slam::StageTimes::kCount> stage_ms_;
  std::vector<KeyframeLink> keyframe_links_;
  std::vector<slam::LoopClosure> closures_;
  std::vector<slam::LoopClosure> wide_edges_;
  std::uint64_t wide_edges_taken_ = 0;
};

/// report.json's `local_map` object: what local mapping did (null where it is off).
void write_local_map(eval::JsonWriter& json, const slam::SlamLoop& loop);

}  // namespace rankslam::app
