#include "live_loop.hpp"

#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/systemd/service_notifier.hpp"

#include <algorithm>
#include <iostream>
#include <optional>
#include <thread>

namespace rankslam::app {

bool run_live_loop(const LiveLoopParts& parts, const std::function<bool()>& stop) {
  hal::DepthCamera& camera = *parts.camera;
  FramePipeline& pipeline = *parts.pipeline;
  nav::PoseMailbox& mailbox = *parts.mailbox;
  const Eigen::Isometry3d T_base_cam = parts.T_base_cam;
  const Eigen::Isometry3d T_cam_base = T_base_cam.inverse();
  const hal::MonotonicClock clock;
  StatusTotals totals;
  const auto update_totals = [&] {
    totals.counts = pipeline.status_counts();
    totals.keyframes = pipeline.loop().keyframes();
    if (parts.wide != nullptr) {
      const hal::NearestImageCounters wide = parts.wide->counters();
      totals.wide = true;
      totals.wide_images = wide.read;
      totals.wide_paired = wide.paired;
    }
    if (parts.checkpointer != nullptr) {
      const Checkpointer::Tally tally = parts.checkpointer->tally();
      totals.checkpoints = true;
      totals.checkpoints_written = tally.written;
      totals.checkpoints_failed = tally.failed;
    }
  };
  update_totals();
  if (parts.status_line != nullptr) parts.status_line->start(clock.now_ns(), totals);
  if (parts.notifier != nullptr) parts.notifier->ready(clock.now_ns());

  hal::RgbdFrame frame;
  bool interrupted = false;
  // The wide-angle camera's last image (read, paired or not) and the fault bit last posted.
  std::int64_t wide_alive_ns = clock.now_ns();
  std::uint64_t wide_images = 0;
  bool wide_fault = parts.wide != nullptr && !parts.wide_camera_open;
  mailbox.set_wide_camera_fault(wide_fault);
  std::optional<std::chrono::steady_clock::time_point> end_time;
  for (;;) {
    const std::int64_t turn_ns = clock.now_ns();
    if (parts.notifier != nullptr) parts.notifier->alive(turn_ns);
    if (parts.status_line != nullptr) {
      update_totals();
      (void)parts.status_line->tick(turn_ns, totals);
    }
    if (stop()) {
      interrupted = true;
      break;
    }
    if (end_time) {
      if (parts.exit_after_end_s >= 0.0 &&
          std::chrono::steady_clock::now() - *end_time >= std::chrono::duration<double>(parts.exit_after_end_s)) {
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    const hal::ReadStatus status = camera.read(frame, parts.read_wait);
    if (parts.replay_camera != nullptr) {
      for (const auto& warning : parts.replay_camera->take_warnings()) std::cerr << "warning: " << warning << "\n";
    }
    if (status == hal::ReadStatus::kEndOfStream) {
      std::cout << "end of stream after " << pipeline.frames() << " frames" << std::endl;
      end_time = std::chrono::steady_clock::now();
      mailbox.set_end_of_stream();
      continue;
    }
    if (status != hal::ReadStatus::kOk) {
      ++totals.empty_reads;
      mailbox.set_camera_fault(status == hal::ReadStatus::kFault);
      continue;
    }
    const std::int64_t capture_ns = clock.now_ns();
    const hal::ImageFrame* paired = nullptr;
    if (parts.wide != nullptr && parts.wide_camera_open) {
      paired = parts.wide->take(frame.stamp_ns, parts.wide_wait);
      if (parts.wide_replay != nullptr) {
        for (const auto& warning : parts.wide_replay->take_warnings()) std::cerr << "warning: " << warning << "\n";
      }
      if (const std::uint64_t read = parts.wide->counters().read; read != wide_images) {
        wide_images = read;
        wide_alive_ns = capture_ns;
      }
      // A dead or silent wide-angle camera costs its images, never the loop: the bit tells.
      const bool fault = !parts.wide->ended() && (parts.wide->last_status() == hal::ReadStatus::kFault ||
                                                  capture_ns - wide_alive_ns > parts.wide_silence_ns);
      if (fault != wide_fault) {
        wide_fault = fault;
        mailbox.set_wide_camera_fault(fault);
        std::cerr << (fault ? "warning: the wide-angle camera failed or went silent; RGB-D only\n"
                            : "the wide-angle camera sends images again\n");
      }
    }
    const slam::FrameResult result = pipeline.process(frame, paired);
    const bool registered =
        result.status == slam::FrameStatus::kTracking || result.status == slam::FrameStatus::kFirstFrame;
    nav::PoseSample sample;
    // The map frame is the base frame at the first camera frame.
    sample.T_map_base = T_base_cam * result.T_world_cam * T_cam_base;
    sample.capture_ns = capture_ns;
    sample.frame_sequence = frame.sequence;
    sample.registered = registered;
    sample.wheels_only = result.status == slam::FrameStatus::kWheels;
    sample.lost = result.status == slam::FrameStatus::kLost;
    sample.wheel_slip = result.wheels.vision_trusted;
    if (result.status != slam::FrameStatus::kFirstFrame && result.features > 0) {
      sample.inlier_percent = static_cast<std::uint8_t>(std::min(100, 100 * result.inliers / result.features));
    }
    if (const auto& sigmas = pipeline.sigmas()) {
      sample.position_sigma_m = sigmas->position_m;
      sample.yaw_sigma_deg = sigmas->yaw_deg;
    }
    // The correction in base frames: T_map_base = T_base_cam * T_world_cam * T_cam_base.
    const Eigen::Isometry3d correction = T_base_cam * result.map_correction * T_cam_base;
    mailbox.post(sample, result.graph_applied ? &correction : nullptr,
                 parts.wheels ? std::optional<std::int64_t>(pipeline.wheel_stamp_ns(frame)) : std::nullopt);
    if (parts.checkpointer != nullptr) (void)parts.checkpointer->offer(pipeline);
  }
  if (parts.notifier != nullptr) parts.notifier->stopping();
  return interrupted;
}

}  // namespace rankslam::app
