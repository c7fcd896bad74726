// Soak of the per-frame path `run` and `replay` share (app::FramePipeline): the simulated office
// loop, decoded into memory once, served over and over with continuing stamps by an in-memory
// camera, through the SLAM loop in the default fused mode with the background optimiser, and
// each frame's pose posted to the pose output (nav::PoseOutput on its own thread, as `run` wires
// it) over a CAN bus that takes frames and receives none.
//
// Every --sample frames (and at 2 000, 20 000 and 100 000) it prints the process RSS
// (/proc/self/statm), the allocations of the tracking thread and of the pose output's thread since
// the warm-up, and the fill of every bounded store it can see. Exit 1 when, after the warm-up
// (--warm-up frames), RSS grows by more than --rss-tolerance, the tracking thread or the pose
// output allocates, or a store exceeds its bound; 2 on a usage or set-up error.
//
// What is not visible from outside the loop is read from the frames' results: the key-frame store
// as the key-frames that got a graph node of their own (a new node or generation) less those
// retired, the pose graph's node slots as the highest node a frame names (slots are reused lowest
// first, so that stays below the capacity).

#include "frame_pipeline.hpp"

#include "rankslam/hal/interfaces.hpp"
#include "rankslam/nav/live_wheels.hpp"
#include "rankslam/nav/pose_output.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include "allocation_counter.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace rankslam {
namespace {

namespace fs = std::filesystem;

constexpr int kLoopFrames = 300;  // one period of the office scene's motion at 30 Hz
constexpr std::int64_t kFrameInterval_ns = 33'333'333;

struct Options {
  long frames = 3000;
  long warm_up = 2000;
  long sample = 10000;
  double rss_tolerance = 0.05;
};

bool parse(int argc, char** argv, Options& options) {
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (i + 1 >= argc) return false;
    const char* value = argv[++i];
    if (arg == "--frames") {
      options.frames = std::atol(value);
    } else if (arg == "--warm-up") {
      options.warm_up = std::atol(value);
    } else if (arg == "--sample") {
      options.sample = std::atol(value);
    } else if (arg == "--rss-tolerance") {
      options.rss_tolerance = std::atof(value);
    } else {
      return false;
    }
  }
  return options.frames > options.warm_up && options.warm_up > 0 && options.sample > 0 && options.rss_tolerance > 0.0;
}

// Resident set size now, MB (/proc/self/statm, second field, pages); read with system calls so
// that sampling it allocates nothing.
double rss_mb() {
  const int fd = ::open("/proc/self/statm", O_RDONLY);
  if (fd < 0) return 0.0;
  char text[128] = {};
  const ssize_t length = ::read(fd, text, sizeof text - 1);
  ::close(fd);
  if (length <= 0) return 0.0;
  const char* resident = std::strchr(text, ' ');
  if (resident == nullptr) return 0.0;
  const double pages = std::strtod(resident + 1, nullptr);
  return pages * static_cast<double>(::sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

// The office loop served over and over with continuing stamps; the images are shared, not copied.
class LoopCamera final : public hal::DepthCamera {
 public:
  LoopCamera(const std::vector<hal::RgbdFrame>& frames, const hal::Calibration& calibration, double first_stamp_s)
      : frames_(frames), calibration_(calibration), first_stamp_s_(first_stamp_s) {}
  [[nodiscard]] std::string open() override { return frames_.empty() ? "no frames" : ""; }
  [[nodiscard]] const hal::Calibration& calibration() const override { return calibration_; }
  [[nodiscard]] hal::ReadStatus read(hal::RgbdFrame& frame, std::chrono::milliseconds /*wait*/) override {
    frame = frames_[next_ % frames_.size()];
    frame.sequence = static_cast<std::uint32_t>(next_);
    frame.stamp_ns = static_cast<std::int64_t>(next_) * kFrameInterval_ns;
    frame.stamp_s = first_stamp_s_ + static_cast<double>(frame.stamp_ns) * 1e-9;
    ++next_;
    return hal::ReadStatus::kOk;
  }
  void close() override {}

 private:
  const std::vector<hal::RgbdFrame>& frames_;
  const hal::Calibration& calibration_;
  double first_stamp_s_;
  std::size_t next_ = 0;
};

// A bus with no other node on it: frames sent are counted, nothing arrives, a receive waits as a
// quiet SocketCAN socket would, so the pose output's thread keeps its own pace.
class QuietCanBus final : public hal::CanBus {
 public:
  [[nodiscard]] std::string open() override { return {}; }
  [[nodiscard]] hal::ReadStatus receive(hal::CanFrame& /*frame*/, std::chrono::milliseconds wait) override {
    std::this_thread::sleep_for(wait);
    return hal::ReadStatus::kTimeout;
  }
  [[nodiscard]] hal::ReadStatus send(const hal::CanFrame& /*frame*/) override {
    ++statistics_.frames_tx;
    return hal::ReadStatus::kOk;
  }
  void close() override {}
  [[nodiscard]] hal::CanBusStatistics statistics() const override { return statistics_; }

 private:
  hal::CanBusStatistics statistics_;
};

std::string load_office_loop(std::vector<hal::RgbdFrame>& frames, replay::Recording& recording) {
  const fs::path directory = fs::temp_directory_path() / ("rankslam_soak_office_" + std::to_string(::getpid()));
  fs::remove_all(directory);
  sim::SimulationOptions options;
  options.scene = "office";
  options.out_dir = directory;
  options.frames = kLoopFrames;
  options.seed = 1;
  std::string error = sim::simulate_recording(options, nullptr);
  if (error.empty()) error = replay::open_recording(directory, recording);
  if (error.empty()) {
    replay::ReplayDepthCamera camera(recording, {});
    error = camera.open();
    hal::RgbdFrame frame;
    while (error.empty() && camera.read(frame, std::chrono::milliseconds(5000)) == hal::ReadStatus::kOk) {
      // The camera reuses its buffers: keep copies.
      hal::RgbdFrame copy = frame;
      copy.rgb = frame.rgb.clone();
      copy.depth = frame.depth.clone();
      copy.ir = frame.ir.clone();
      frames.push_back(copy);
    }
    camera.close();
    if (error.empty() && frames.size() != static_cast<std::size_t>(kLoopFrames)) {
      error = "read " + std::to_string(frames.size()) + " of " + std::to_string(kLoopFrames) + " frames";
    }
  }
  std::error_code ignored;
  fs::remove_all(directory, ignored);
  return error;
}

struct Sample {
  long frame = 0;
  double rss_mb = 0.0;
  long tracking_allocations = 0;
  long frames_that_allocated = 0;
  long output_allocations = 0;
  int stored_keyframes = 0;
  int graph_node_slots = 0;
  std::size_t map_points = 0;
  int loop_closures = 0;
  std::size_t trajectory = 0;
  int tracking = 0;
  int lost = 0;
};

int soak(const Options& options) {
  std::vector<hal::RgbdFrame> frames;
  replay::Recording recording;
  if (const std::string error = load_office_loop(frames, recording); !error.empty()) {
    std::fprintf(stderr, "error: %s\n", error.c_str());
    return 2;
  }
  const double rss_frames_mb = rss_mb();
  const hal::Calibration& calibration = recording.calibration;
  LoopCamera camera(frames, calibration, frames.front().stamp_s);
  if (const std::string error = camera.open(); !error.empty()) {
    std::fprintf(stderr, "error: %s\n", error.c_str());
    return 2;
  }

  // As `run` sets it up: default SLAM configuration, the solves on the background optimiser, the
  // trajectory of the robot configuration's default capacity, no frame log.
  const slam::SlamConfig config;
  app::PipelineOptions pipeline_options;
  pipeline_options.max_frames = 100000;
  pipeline_options.recording_clock = true;
  pipeline_options.synchronous_backend = false;
  pipeline_options.frame_log = false;
  app::FramePipeline pipeline(config, calibration, nullptr, pipeline_options);
  slam::SlamLoop& loop = pipeline.loop();
  const Eigen::Isometry3d T_base_cam = calibration.rgb.T_base_cam;
  const Eigen::Isometry3d T_cam_base = T_base_cam.inverse();

  nav::PoseMailbox mailbox;
  nav::LiveWheels wheels;  // not enabled: no wheels on the office loop
  QuietCanBus bus;
  const hal::MonotonicClock clock;
  nav::PoseOutputOptions output_options;
  nav::PoseOutput output(output_options, bus, clock, mailbox, wheels);
  std::atomic<bool> stop_output{false};
  std::atomic<bool> counting_output{false};
  std::atomic<long> output_allocations{0};

  std::vector<Sample> samples;
  samples.reserve(static_cast<std::size_t>(options.frames / options.sample + 8));
  std::printf("soak: %ld frames of the simulated office loop (%d frames, stamps continuing), fused mode, background "
              "optimiser, pose output; warm-up %ld frames\n",
              options.frames, kLoopFrames, options.warm_up);
  std::printf("RSS with the decoded frames, before the pipeline %.1f MB; with the pipeline set up %.1f MB\n",
              rss_frames_mb, rss_mb());
  std::printf("bounds: key-frame store and graph nodes %d, map points %d, trajectory %zu\n", config.keyframe_capacity,
              config.map.max_points, pipeline_options.max_frames);
  std::printf("%8s %9s %8s %10s %10s %9s %10s %10s %9s %10s %9s %6s\n", "frame", "rss_mb", "rss_%", "alloc_trk",
              "frames_alc", "alloc_out", "keyframes", "graph_node", "map_pts", "closures", "traj", "lost");
  std::printf("(alloc_trk: allocations of the tracking thread in its frames since the warm-up, on the warm-up row "
              "during it; alloc_out: the pose output thread's since the warm-up; keyframes: in the store; graph_node: "
              "node slots used)\n");
  std::fflush(stdout);

  double rss_at_warm_up_mb = 0.0;
  double largest_rss_mb = 0.0;
  long largest_rss_frame = 0;
  bool store_over_bound = false;
  bool map_over_bound = false;
  bool trajectory_over_bound = false;
  int lost = 0;
  int tracking = 0;
  long frames_that_allocated = 0;
  long first_allocating_frame = -1;
  long frame_allocations = 0;
  int stored_keyframes = 0;
  int highest_node = -1;
  int keyframes_without_node = 0;
  int latest_node = -1;
  std::uint32_t latest_generation = 0;
  const auto start = std::chrono::steady_clock::now();
  {
    // One counter over the whole run; each thread's count is read as a difference on that thread.
    const test_support::CountAllocations count;
    std::thread sender([&] {
      long base = count.this_thread_allocations();
      bool counting = false;
      wheels.mark_receiving();
      while (!stop_output.load()) {
        output.step();
        const bool now_counting = counting_output.load();
        if (now_counting && !counting) base = count.this_thread_allocations();
        counting = now_counting;
        if (counting) output_allocations.store(count.this_thread_allocations() - base);
      }
    });
    const auto take_sample = [&](long frame_number) {
      Sample sample;
      sample.frame = frame_number;
      sample.rss_mb = rss_mb();
      sample.tracking_allocations = frame_allocations;
      sample.frames_that_allocated = frames_that_allocated;
      sample.output_allocations = output_allocations.load();
      sample.stored_keyframes = stored_keyframes - loop.retired_keyframes();
      sample.graph_node_slots = highest_node + 1;
      sample.map_points = loop.map().size();
      sample.loop_closures = loop.loop_closures();
      sample.trajectory = pipeline.trajectory().size();
      sample.tracking = tracking;
      sample.lost = lost;
      store_over_bound = store_over_bound || sample.stored_keyframes > config.keyframe_capacity ||
                         sample.graph_node_slots > config.keyframe_capacity;
      map_over_bound = map_over_bound || sample.map_points > loop.map().capacity();
      trajectory_over_bound = trajectory_over_bound || sample.trajectory > pipeline_options.max_frames;
      if (frame_number == options.warm_up) rss_at_warm_up_mb = sample.rss_mb;
      if (frame_number >= options.warm_up && sample.rss_mb > largest_rss_mb) {
        largest_rss_mb = sample.rss_mb;
        largest_rss_frame = frame_number;
      }
      const double growth = rss_at_warm_up_mb > 0.0 ? 100.0 * (sample.rss_mb / rss_at_warm_up_mb - 1.0) : 0.0;
      std::printf("%8ld %9.1f %+8.2f %10ld %10ld %9ld %6d/%-3d %6d/%-3d %9zu %10d %9zu %6d\n", sample.frame,
                  sample.rss_mb, growth, sample.tracking_allocations, sample.frames_that_allocated,
                  sample.output_allocations, sample.stored_keyframes, config.keyframe_capacity,
                  sample.graph_node_slots, config.keyframe_capacity, sample.map_points, sample.loop_closures,
                  sample.trajectory, sample.lost);
      std::fflush(stdout);
      samples.push_back(sample);
    };

    hal::RgbdFrame frame;
    for (long i = 0; i < options.frames; ++i) {
      if (i == options.warm_up) {
        take_sample(i);
        frame_allocations = 0;
        counting_output = true;
      }
      const long before = count.this_thread_allocations();
      if (camera.read(frame, std::chrono::milliseconds(100)) != hal::ReadStatus::kOk) continue;
      const std::int64_t capture_ns = clock.now_ns();
      const slam::FrameResult result = pipeline.process(frame);
      // The sample as `run` posts it.
      nav::PoseSample pose;
      pose.T_map_base = T_base_cam * result.T_world_cam * T_cam_base;
      pose.capture_ns = capture_ns;
      pose.frame_sequence = frame.sequence;
      pose.registered =
          result.status == slam::FrameStatus::kTracking || result.status == slam::FrameStatus::kFirstFrame;
      pose.wheels_only = result.status == slam::FrameStatus::kWheels;
      pose.wheel_slip = result.wheels.vision_trusted;
      if (result.status != slam::FrameStatus::kFirstFrame && result.features > 0) {
        pose.inlier_percent = static_cast<std::uint8_t>(std::min(100, 100 * result.inliers / result.features));
      }
      const Eigen::Isometry3d correction = T_base_cam * result.map_correction * T_cam_base;
      mailbox.post(pose, result.graph_applied ? &correction : nullptr, std::nullopt);
      tracking += result.status == slam::FrameStatus::kTracking ? 1 : 0;
      lost += result.status == slam::FrameStatus::kFailed ? 1 : 0;
      if (result.keyframe && result.keyframe_node < 0) ++keyframes_without_node;
      if (result.keyframe_node >= 0 &&
          (result.keyframe_node != latest_node || result.keyframe_generation != latest_generation)) {
        ++stored_keyframes;
        latest_node = result.keyframe_node;
        latest_generation = result.keyframe_generation;
        highest_node = std::max(highest_node, latest_node);
      }
      const long allocations = count.this_thread_allocations() - before;
      frame_allocations += allocations;
      if (i >= options.warm_up && allocations > 0) {
        ++frames_that_allocated;
        if (first_allocating_frame < 0) first_allocating_frame = i;
      }
      const long done = i + 1;
      if (done > options.warm_up && (done % options.sample == 0 || done == 20000 || done == options.frames)) {
        take_sample(done);
      }
    }
    stop_output = true;
    sender.join();
  }
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const nav::PoseOutputCounters& counters = output.pose_counters();
  const Sample& last = samples.back();
  const double growth = 100.0 * (largest_rss_mb / rss_at_warm_up_mb - 1.0);
  std::printf("%ld frames in %.0f s (%.1f frames/s): %d tracked, %d lost, %d key-frames taken, %d retired, %d loop "
              "closures; pose output: %llu pose cycles (%llu lost), %llu heartbeats, %llu frames on the bus\n",
              options.frames, elapsed_s, static_cast<double>(options.frames) / elapsed_s, tracking, lost,
              loop.keyframes(), loop.retired_keyframes(), loop.loop_closures(),
              static_cast<unsigned long long>(counters.pose_cycles), static_cast<unsigned long long>(counters.lost_cycles),
              static_cast<unsigned long long>(counters.heartbeats),
              static_cast<unsigned long long>(bus.statistics().frames_tx));
  std::printf("RSS after the warm-up %.1f MB, largest after it %.1f MB at frame %ld (%+.2f %%, tolerance %.1f %%)\n",
              rss_at_warm_up_mb, largest_rss_mb, largest_rss_frame, growth, 100.0 * options.rss_tolerance);

  bool failed = false;
  const auto fail = [&](const std::string& what) {
    std::printf("FAIL: %s\n", what.c_str());
    failed = true;
  };
  if (largest_rss_mb > (1.0 + options.rss_tolerance) * rss_at_warm_up_mb) fail("RSS grew after the warm-up");
  if (last.tracking_allocations != 0) {
    fail(std::to_string(last.frames_that_allocated) + " steady-state frames allocated on the tracking thread (" +
         std::to_string(last.tracking_allocations) + " allocations), the first at frame " +
         std::to_string(first_allocating_frame));
  }
  if (last.output_allocations != 0) fail("the pose output allocated in the steady state");
  if (store_over_bound) fail("the key-frame store or the pose graph held more than its capacity");
  if (keyframes_without_node > 0) fail(std::to_string(keyframes_without_node) + " key-frames found the pose graph full");
  if (map_over_bound) fail("the map held more points than its capacity");
  if (trajectory_over_bound) fail("the trajectory held more poses than its capacity");
  // A soak that stopped tracking proves nothing about the tracking path.
  if (tracking < options.frames - options.frames / 100) fail("fewer than 99 % of the frames tracked");
  if (loop.retired_keyframes() == 0 && options.frames > 5000) fail("no key-frame was retired: the store never filled");
  if (counters.heartbeats == 0 || counters.pose_cycles == 0) fail("the pose output sent nothing");
  if (!failed) std::printf("PASS\n");
  return failed ? 1 : 0;
}

}  // namespace
}  // namespace rankslam

int main(int argc, char** argv) {
  rankslam::Options options;
  if (!rankslam::parse(argc, argv, options)) {
    std::fprintf(stderr,
                 "usage: %s [--frames N (3000)] [--warm-up N (2000)] [--sample N (10000)] [--rss-tolerance F (0.05)]\n",
                 argv[0]);
    return 2;
  }
  return rankslam::soak(options);
}
