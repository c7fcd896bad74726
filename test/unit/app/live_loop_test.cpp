// The live loop of `rankslam run` with the service notifier it feeds (Type=notify, WatchdogSec=):
// a socket of the test's own plays systemd's NOTIFY_SOCKET, the real loop runs a replayed
// recording through the SLAM pipeline, and a camera wrapper then stops delivering (the replay
// past its end, each read timing out) or sticks inside read(). READY=1 must come when the loop
// starts, WATCHDOG=1 while the loop goes round whether or not frames come, none while it is
// stuck, STOPPING=1 at the end. No time is asserted: only which datagrams arrive.
#include "checkpointer.hpp"
#include "commands.hpp"
#include "exit_codes.hpp"
#include "live_loop.hpp"
#include "status_line.hpp"

#include "allocation_counter.hpp"
#include "rankslam/hal/file_set.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/systemd/service_notifier.hpp"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <condition_variable>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <mutex>
#include <regex>
#include <string>
#include <thread>

namespace rankslam::app {
namespace {

namespace fs = std::filesystem;

/// A bound AF_UNIX datagram socket standing in for systemd's notify socket.
class NotifySocket {
 public:
  explicit NotifySocket(const fs::path& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    const std::string text = path.string();
    if (fd_ < 0 || text.size() >= sizeof address.sun_path) return;
    text.copy(address.sun_path, text.size());
    bound_ = ::bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) == 0;
  }
  ~NotifySocket() {
    if (fd_ >= 0) ::close(fd_);
    std::error_code ignored;
    fs::remove(path_, ignored);
  }
  [[nodiscard]] bool bound() const { return bound_; }

  /// The next datagram within `wait_ms`, or "" when none came.
  std::string receive(int wait_ms) {
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, wait_ms) != 1) return {};
    char buffer[512];
    const ssize_t n = ::recv(fd_, buffer, sizeof buffer, 0);
    return n > 0 ? std::string(buffer, static_cast<std::size_t>(n)) : std::string();
  }
  /// The next datagram other than WATCHDOG=1 within `wait_ms` each.
  std::string receive_other_than_watchdog(int wait_ms) {
    for (;;) {
      std::string message = receive(wait_ms);
      if (message != "WATCHDOG=1") return message;
    }
  }
  /// Discards what has arrived; how many datagrams that was.
  int drain() {
    int n = 0;
    while (!receive(0).empty()) ++n;
    return n;
  }

 private:
  fs::path path_;
  int fd_ = -1;
  bool bound_ = false;
};

/// A replay camera that can be told to deliver, to stop delivering (each read waits its budget
/// and times out, as a silent live camera does; so does the end of the recording), or to stick
/// inside read() until released, as a hung driver would.
class ScriptedCamera final : public hal::DepthCamera {
 public:
  enum class Mode { kDeliver, kSilent, kStuck };
  explicit ScriptedCamera(replay::ReplayDepthCamera& replay) : replay_(replay) {}

  std::string open() override { return replay_.open(); }
  const hal::Calibration& calibration() const override { return replay_.calibration(); }
  void close() override { replay_.close(); }
  hal::ReadStatus read(hal::RgbdFrame& frame, std::chrono::milliseconds wait) override {
    if (mode_.load() == Mode::kStuck) {
      std::unique_lock lock(mutex_);
      stuck_ = true;
      changed_.notify_all();
      changed_.wait(lock, [&] { return mode_.load() != Mode::kStuck; });
      stuck_ = false;
    }
    if (mode_.load() == Mode::kDeliver) {
      const hal::ReadStatus status = replay_.read(frame, wait);
      if (status == hal::ReadStatus::kOk) {
        ++delivered_;
        return status;
      }
    }
    ++silent_reads_;
    std::this_thread::sleep_for(wait);
    return hal::ReadStatus::kTimeout;
  }

  void set_mode(Mode mode) {
    std::lock_guard lock(mutex_);
    mode_ = mode;
    changed_.notify_all();
  }
  /// Blocks until the loop sits inside read() in kStuck mode.
  void wait_stuck() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return stuck_; });
  }
  [[nodiscard]] int delivered() const { return delivered_.load(); }
  [[nodiscard]] int silent_reads() const { return silent_reads_.load(); }

 private:
  replay::ReplayDepthCamera& replay_;
  std::atomic<Mode> mode_{Mode::kDeliver};
  std::atomic<int> delivered_{0};
  std::atomic<int> silent_reads_{0};
  std::mutex mutex_;
  std::condition_variable changed_;
  bool stuck_ = false;
};

class LiveLoopTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("rankslam-live-loop-" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    ::unsetenv("NOTIFY_SOCKET");
    ::unsetenv("WATCHDOG_USEC");
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }
  /// The simulated office's first `frames` frames as a recording in dir_/recording.
  void simulate_office(int frames, replay::Recording& recording) { simulate("office", frames, recording); }
  /// The same of the simulated corridor loop, with its wide-angle images (one per third frame).
  void simulate_corridor(int frames, replay::Recording& recording) { simulate("corridor-loop", frames, recording); }
  void simulate(const char* scene, int frames, replay::Recording& recording) {
    sim::SimulationOptions simulation;
    simulation.scene = scene;
    simulation.out_dir = dir_ / "recording";
    simulation.frames = frames;
    ASSERT_EQ(sim::simulate_recording(simulation, nullptr), "");
    ASSERT_EQ(replay::open_recording(simulation.out_dir, recording), "");
  }
  fs::path dir_;
};

TEST_F(LiveLoopTest, WatchdogFollowsTheLoopNotTheCamera) {
  sim::SimulationOptions simulation;
  simulation.scene = "office";
  simulation.out_dir = dir_ / "recording";
  simulation.frames = 12;
  ASSERT_EQ(sim::simulate_recording(simulation, nullptr), "");
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(simulation.out_dir, recording), "");
  replay::ReplayDepthCamera replay(recording, replay::ReplayOptions{});
  ScriptedCamera camera(replay);
  ASSERT_EQ(camera.open(), "");

  NotifySocket socket(dir_ / "notify");
  ASSERT_TRUE(socket.bound());
  ::setenv("NOTIFY_SOCKET", (dir_ / "notify").c_str(), 1);
  ::setenv("WATCHDOG_USEC", "20000", 1);  // WATCHDOG=1 at most every 10 ms
  ::unsetenv("WATCHDOG_PID");
  systemd::ServiceNotifier notifier;
  ASSERT_TRUE(notifier.active());
  ASSERT_EQ(notifier.watchdog_period_ns(), 10'000'000);

  PipelineOptions pipeline_options;
  pipeline_options.max_frames = 100;
  FramePipeline pipeline(slam::SlamConfig{}, camera.calibration(), nullptr, pipeline_options);
  nav::PoseMailbox mailbox;
  int status_pipe[2];
  ASSERT_EQ(::pipe2(status_pipe, O_CLOEXEC | O_NONBLOCK), 0);
  StatusLine status_line(100'000'000, status_pipe[1]);
  // Every checkpoint fails (a full disk): the status line says so while the loop goes on.
  Checkpointer checkpointer(pipeline.loop(), pipeline_options.max_frames, 0.0,
                            [](const CheckpointContents&) { return std::string("map.rsm: No space left on device"); });

  LiveLoopParts parts;
  parts.camera = &camera;
  parts.pipeline = &pipeline;
  parts.mailbox = &mailbox;
  parts.read_wait = std::chrono::milliseconds(5);
  parts.exit_after_end_s = -1.0;
  parts.notifier = &notifier;
  parts.status_line = &status_line;
  parts.checkpointer = &checkpointer;
  std::atomic<bool> stop{false};
  bool interrupted = false;
  std::thread loop([&] { interrupted = run_live_loop(parts, [&] { return stop.load(); }); });

  // Frames flow: READY=1 first, then the loop's watchdog while frames are processed (the first
  // frames may take longer than a read's 5 ms to decode: those turns feed it too).
  EXPECT_EQ(socket.receive(30'000), "READY=1");
  int watchdogs = 0;
  while ((watchdogs < 3 || camera.delivered() < 3) && socket.receive(30'000) == "WATCHDOG=1") ++watchdogs;
  EXPECT_GE(watchdogs, 3);
  EXPECT_GE(camera.delivered(), 3);

  // The camera stops delivering: the loop keeps going round on read timeouts, so the watchdog goes on.
  camera.set_mode(ScriptedCamera::Mode::kSilent);
  const int silent_before = camera.silent_reads();
  (void)socket.drain();
  watchdogs = 0;
  while (watchdogs < 5 && socket.receive(30'000) == "WATCHDOG=1") ++watchdogs;
  EXPECT_EQ(watchdogs, 5) << "a camera without frames must not starve the watchdog";
  // At most the read under way when the mode changed brought a frame.
  const int delivered = camera.delivered();
  EXPECT_GT(camera.silent_reads(), silent_before);
  while (socket.receive(30'000) == "WATCHDOG=1" && watchdogs < 10) ++watchdogs;
  EXPECT_EQ(camera.delivered(), delivered);

  // The loop sticks inside read(): no WATCHDOG=1 (20 watchdog periods and more of silence).
  camera.set_mode(ScriptedCamera::Mode::kStuck);
  camera.wait_stuck();
  (void)socket.drain();
  EXPECT_EQ(socket.receive(200), "") << "a stuck loop must let the watchdog expire";

  // Going round again feeds it again; stopping says STOPPING=1.
  camera.set_mode(ScriptedCamera::Mode::kSilent);
  EXPECT_EQ(socket.receive(30'000), "WATCHDOG=1");
  stop = true;
  loop.join();
  EXPECT_TRUE(interrupted);
  EXPECT_EQ(socket.receive_other_than_watchdog(1000), "STOPPING=1");
  EXPECT_GT(notifier.watchdog_sent(), 8u);
  EXPECT_EQ(notifier.failures(), 0u);

  // The journal's status line came from the loop's thread: frames by status, reads without a frame.
  char text[65536];
  const ssize_t n = ::read(status_pipe[0], text, sizeof text);
  ::close(status_pipe[0]);
  ::close(status_pipe[1]);
  ASSERT_GT(n, 0);
  const std::string lines(text, static_cast<std::size_t>(n));
  EXPECT_EQ(lines.rfind("status: last ", 0), 0u) << lines;
  EXPECT_NE(lines.find("frames/s, TRACKING "), std::string::npos) << lines;
  EXPECT_NE(lines.find(", LOST "), std::string::npos) << lines;
  EXPECT_NE(lines.find("camera reads without a frame "), std::string::npos) << lines;
  EXPECT_NE(lines.find(" MB, checkpoints written 0, failed "), std::string::npos) << lines;
  EXPECT_TRUE(std::regex_search(lines, std::regex("checkpoints written 0, failed [1-9][0-9]*\n"))) << lines;
  checkpointer.stop();
  EXPECT_GT(checkpointer.counters().failed, 0U);
  EXPECT_EQ(checkpointer.counters().written, 0U);
  camera.close();
}

// A wide-angle camera that delivers `live_reads` images, then faults on every read, as an
// unplugged device does.
class DyingImageCamera final : public hal::Camera {
 public:
  DyingImageCamera(replay::ReplayImageCamera& replay, int live_reads) : replay_(replay), live_reads_(live_reads) {}
  std::string open() override { return replay_.open(); }
  void close() override { replay_.close(); }
  hal::ReadStatus read(hal::ImageFrame& frame, std::chrono::milliseconds wait) override {
    if (reads_++ >= live_reads_) return hal::ReadStatus::kFault;
    return replay_.read(frame, wait);
  }

 private:
  replay::ReplayImageCamera& replay_;
  int live_reads_;
  int reads_ = 0;
};

// A wide-angle camera that dies costs its images, never the loop: every frame is processed, the
// images before the death were paired with their frames, and the journal says RGB-D only.
TEST_F(LiveLoopTest, AWideAngleCameraThatDiesLeavesTheLoopToTheRgbdCamera) {
  // wide-angle images at frames 0, 3, 6
  replay::Recording recording;
  simulate_corridor(9, recording);
  ASSERT_EQ(recording.fisheye.size(), 3U);
  replay::ReplayDepthCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  replay::ReplayImageCamera images(recording, {});
  DyingImageCamera wide_camera(images, 2);
  ASSERT_EQ(wide_camera.open(), "");
  hal::NearestImage wide(wide_camera, 20'000'000);
  wide.allocate(recording.calibration.fisheye->width, recording.calibration.fisheye->height, CV_8UC3);

  PipelineOptions pipeline_options;
  pipeline_options.max_frames = 100;
  FramePipeline pipeline(slam::SlamConfig{}, camera.calibration(), nullptr, pipeline_options);
  nav::PoseMailbox mailbox;
  LiveLoopParts parts;
  parts.camera = &camera;
  parts.pipeline = &pipeline;
  parts.mailbox = &mailbox;
  parts.exit_after_end_s = 0.0;
  parts.wide = &wide;
  parts.wide_wait = std::chrono::milliseconds(2000);
  parts.wide_silence_ns = 3'600'000'000'000;  // only the failed reads tell here
  std::ostringstream err;
  std::streambuf* const old_err = std::cerr.rdbuf(err.rdbuf());
  const bool interrupted = run_live_loop(parts, [] { return false; });
  std::cerr.rdbuf(old_err);
  EXPECT_FALSE(interrupted);
  EXPECT_EQ(pipeline.frames(), 9U);
  EXPECT_EQ(wide.counters().read, 2U);
  EXPECT_EQ(wide.counters().paired, 2U);
  EXPECT_GE(wide.counters().faults, 6U);  // asked again at every frame from the 4th on
  EXPECT_NE(err.str().find("wide-angle camera failed or went silent; RGB-D only"), std::string::npos) << err.str();
  camera.close();
  wide_camera.close();
}

// Pairing the wide-angle images with the frames allocates nothing on the loop's thread once the
// first image is in (the replay's decoding runs on its reader thread).
TEST_F(LiveLoopTest, PairingWideAngleImagesAllocatesNothingOnTheLoopsThread) {
  replay::Recording recording;
  simulate_corridor(9, recording);
  replay::ReplayDepthCamera camera(recording, {});
  replay::ReplayImageCamera images(recording, {});
  ASSERT_EQ(camera.open(), "");
  ASSERT_EQ(images.open(), "");
  hal::NearestImage wide(images, 20'000'000);
  wide.allocate(recording.calibration.fisheye->width, recording.calibration.fisheye->height, CV_8UC3);
  hal::RgbdFrame frame;
  ASSERT_EQ(camera.read(frame, std::chrono::milliseconds(2000)), hal::ReadStatus::kOk);
  ASSERT_NE(wide.take(frame.stamp_ns, std::chrono::milliseconds(2000)), nullptr);
  int paired = 0;
  long allocations = 0;
  {
    const test_support::CountAllocations count;
    while (camera.read(frame, std::chrono::milliseconds(2000)) == hal::ReadStatus::kOk) {
      paired += wide.take(frame.stamp_ns, std::chrono::milliseconds(2000)) != nullptr ? 1 : 0;
    }
    allocations = count.this_thread_allocations();
  }
  EXPECT_EQ(paired, 2);  // frames 3 and 6
  EXPECT_EQ(allocations, 0);
}

// The wide-angle camera's part of the SLAM loop allocates nothing on the loop's thread: each
// key-frame's image is copied into the mapper's queue, its registrations taken from it, from the
// second frame on (the mapper's SIFT runs on its own thread).
TEST_F(LiveLoopTest, WideAngleKeyFramesAllocateNothingOnTheLoopsThread) {
  replay::Recording recording;
  simulate_corridor(120, recording);
  replay::ReplayDepthCamera camera(recording, {});
  replay::ReplayImageCamera images(recording, {});
  ASSERT_EQ(camera.open(), "");
  ASSERT_EQ(images.open(), "");
  hal::NearestImage wide(images, 20'000'000);
  wide.allocate(recording.calibration.fisheye->width, recording.calibration.fisheye->height, CV_8UC3);
  PipelineOptions pipeline_options;
  pipeline_options.max_frames = 100;
  slam::SlamConfig config;
  config.wide.recent_candidates = 2;
  config.wide.loop_candidates = 2;
  config.wide.place_candidates = 2;
  FramePipeline pipeline(config, camera.calibration(), nullptr, pipeline_options);
  ASSERT_NE(pipeline.loop().wide_counters(), nullptr);
  hal::RgbdFrame frame;
  ASSERT_EQ(camera.read(frame, std::chrono::milliseconds(2000)), hal::ReadStatus::kOk);
  (void)pipeline.process(frame, wide.take(frame.stamp_ns, std::chrono::milliseconds(2000)));
  long allocations = 0;
  {
    const test_support::CountAllocations count;
    while (camera.read(frame, std::chrono::milliseconds(2000)) == hal::ReadStatus::kOk) {
      (void)pipeline.process(frame, wide.take(frame.stamp_ns, std::chrono::milliseconds(2000)));
    }
    allocations = count.this_thread_allocations();
  }
  pipeline.finish();
  EXPECT_EQ(pipeline.frames(), 120U);
  const slam::WideCounters* used = pipeline.loop().wide_counters();
  ASSERT_NE(used, nullptr);
  const std::uint64_t used_images = used->images;
  EXPECT_GE(used_images, 2U) << "a key-frame after the first gave the mapper its image";
  EXPECT_EQ(allocations, 0);
}

// The unit's instance reaches `run` as --can-interface: it is the interface used, and one that
// differs from the file's is said. The host has no CAN interface: the start-up error names it.
// Checkpoints (map.checkpoint_s): the loop's thread only copies (no allocation) and goes on; the
// writer gets the map and trajectory as they were at the offer; a checkpoint due while the
// writer is busy is skipped and counted; stop() waits for the write; the map file loads.
TEST_F(LiveLoopTest, CheckpointsCopyOnTheLoopsThreadAndWriteOnTheirOwn) {
  replay::Recording recording;
  simulate_office(10, recording);
  if (HasFatalFailure()) return;
  replay::ReplayDepthCamera camera(recording, replay::ReplayOptions{});
  ASSERT_EQ(camera.open(), "");
  PipelineOptions pipeline_options;
  pipeline_options.max_frames = 100;
  const slam::SlamConfig config;
  FramePipeline pipeline(config, camera.calibration(), nullptr, pipeline_options);
  hal::RgbdFrame frame;
  while (camera.read(frame, std::chrono::seconds(5)) == hal::ReadStatus::kOk) (void)pipeline.process(frame);
  ASSERT_GE(pipeline.loop().keyframes(), 1);

  const fs::path map_path = dir_ / "map.rsm";
  std::mutex gate_mutex;
  std::condition_variable gate_changed;
  bool gate_open = false;
  std::size_t written_poses = 0;
  std::thread::id writer_thread;
  std::vector<unsigned char> bytes;
  Checkpointer checkpointer(pipeline.loop(), pipeline_options.max_frames, 0.0, [&](const CheckpointContents& contents) {
    std::unique_lock lock(gate_mutex);
    gate_changed.wait(lock, [&] { return gate_open; });
    written_poses = contents.trajectory.size();
    writer_thread = std::this_thread::get_id();
    return slam::save_map_file(map_path, contents.map, bytes);
  });
  long allocations = 0;
  bool first = false;
  bool second = true;
  {
    const test_support::CountAllocations count;
    first = checkpointer.offer(pipeline);
    second = checkpointer.offer(pipeline);  // the writer is still held at the gate
    allocations = count.this_thread_allocations();
  }
  EXPECT_TRUE(first);
  EXPECT_FALSE(second);
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(checkpointer.counters().skipped, 1U);
  {
    const std::lock_guard lock(gate_mutex);
    gate_open = true;
  }
  gate_changed.notify_all();
  checkpointer.stop();
  const Checkpointer::Counters counters = checkpointer.counters();
  EXPECT_EQ(counters.written, 1U) << counters.last_error;
  EXPECT_EQ(counters.failed, 0U);
  EXPECT_FALSE(checkpointer.offer(pipeline)) << "offer after stop()";
  EXPECT_NE(writer_thread, std::this_thread::get_id());
  EXPECT_EQ(written_poses, pipeline.trajectory().size());

  FramePipeline restarted(config, camera.calibration(), nullptr, pipeline_options);
  ASSERT_EQ(restarted.load_map(map_path), kExitOk);
  EXPECT_EQ(restarted.loop().keyframe_store().size(), pipeline.loop().keyframe_store().size());
}

/// The file's inode: a rewrite renames a new file over it, so it changes (a hard link to the old
/// file keeps its inode from being reused).
ino_t inode_of(const fs::path& path) {
  struct stat status {};
  return ::stat(path.c_str(), &status) == 0 ? status.st_ino : 0;
}

// A camera standing still changes nothing in the map: a checkpoint then leaves the file the
// writer last wrote alone (no rewrite of the whole map every interval); a file moved away, or a
// map that changed, is written, and what is on disk always loads as the map.
TEST_F(LiveLoopTest, ACheckpointLeavesAnUnchangedMapFileAlone) {
  replay::Recording recording;
  simulate_office(40, recording);
  if (HasFatalFailure()) return;
  replay::ReplayDepthCamera camera(recording, replay::ReplayOptions{});
  ASSERT_EQ(camera.open(), "");
  PipelineOptions pipeline_options;
  pipeline_options.max_frames = 200;
  const slam::SlamConfig config;
  FramePipeline pipeline(config, camera.calibration(), nullptr, pipeline_options);
  hal::RgbdFrame frame;
  for (int i = 0; i < 20; ++i) {
    ASSERT_EQ(camera.read(frame, std::chrono::seconds(5)), hal::ReadStatus::kOk);
    (void)pipeline.process(frame);
  }
  const int keyframes_before = pipeline.loop().keyframes();

  const fs::path out = dir_ / "out";
  ASSERT_EQ(hal::prepare_output_directory(out), "");
  const fs::path map_path = dir_ / "map.rsm";
  const fs::path kept = dir_ / "kept.rsm";
  CheckpointWriter writer(config, camera.calibration(), map_path, out, OutputFrame::kCamera,
                          Eigen::Isometry3d::Identity(), "test");
  std::unique_ptr<slam::MapSnapshot> snapshot = pipeline.loop().make_map_snapshot();
  const auto checkpoint = [&] {
    pipeline.loop().snapshot_map(*snapshot);
    return writer({*snapshot, pipeline.trajectory(), pipeline.frames()});
  };
  ASSERT_EQ(checkpoint(), "");
  fs::create_hard_link(map_path, kept);

  // A second of standing still: the last image again and again.
  hal::RgbdFrame still = frame;
  still.rgb = frame.rgb.clone();
  still.depth = frame.depth.clone();
  for (int i = 0; i < 30; ++i) {
    still.stamp_ns += 33'333'333;
    still.stamp_s += 0.033333333;
    (void)pipeline.process(still);
  }
  ASSERT_EQ(pipeline.loop().keyframes(), keyframes_before);
  ASSERT_EQ(checkpoint(), "");
  EXPECT_EQ(inode_of(map_path), inode_of(kept)) << "an unchanged map was written again";

  fs::remove(map_path);  // moved away by the user: the next checkpoint writes it again
  ASSERT_EQ(checkpoint(), "");
  ASSERT_TRUE(fs::is_regular_file(map_path));
  fs::remove(kept);
  fs::create_hard_link(map_path, kept);

  while (camera.read(frame, std::chrono::seconds(5)) == hal::ReadStatus::kOk) (void)pipeline.process(frame);
  ASSERT_GT(pipeline.loop().keyframes(), keyframes_before);
  ASSERT_EQ(checkpoint(), "");
  EXPECT_NE(inode_of(map_path), inode_of(kept)) << "a changed map was not written";
  FramePipeline restarted(config, camera.calibration(), nullptr, pipeline_options);
  ASSERT_EQ(restarted.load_map(map_path), kExitOk);
  EXPECT_EQ(restarted.loop().keyframe_store().size(), pipeline.loop().keyframe_store().size());
}

TEST_F(LiveLoopTest, CanInterfaceOptionWinsOverTheConfigurationAndIsSaid) {
  sim::SimulationOptions simulation;
  simulation.scene = "office";
  simulation.out_dir = dir_ / "recording";
  simulation.frames = 2;
  ASSERT_EQ(sim::simulate_recording(simulation, nullptr), "");
  std::ofstream(dir_ / "robot.yaml") << "camera: {source: 'replay:recording'}\ncan: {interface: rsfile0}\n";

  const auto run = [&](const std::string& can_interface, std::string& said) {
    RunArgs args;
    args.config = dir_ / "robot.yaml";
    args.out = dir_ / "out";
    args.can_interface = can_interface;
    std::ostringstream out;
    std::ostringstream err;
    std::streambuf* const old_out = std::cout.rdbuf(out.rdbuf());
    std::streambuf* const old_err = std::cerr.rdbuf(err.rdbuf());
    const int code = run_live(args);
    std::cout.rdbuf(old_out);
    std::cerr.rdbuf(old_err);
    said = out.str() + err.str();
    return code;
  };
  std::string said;
  EXPECT_EQ(run("rsunit0", said), kExitInput);
  EXPECT_NE(said.find("--can-interface rsunit0 overrides can.interface rsfile0"), std::string::npos) << said;
  EXPECT_NE(said.find("error: CAN interface rsunit0:"), std::string::npos) << said;
  EXPECT_EQ(said.find("CAN interface rsfile0:"), std::string::npos) << said;

  EXPECT_EQ(run("rsfile0", said), kExitInput);  // agreeing: nothing to say
  EXPECT_EQ(said.find("overrides"), std::string::npos) << said;
  EXPECT_EQ(run("", said), kExitInput);         // no option: the file's
  EXPECT_NE(said.find("error: CAN interface rsfile0:"), std::string::npos) << said;
}

TEST(ServiceNotifier, DoesNothingOutsideAServiceAndHalvesTheWatchdogInterval) {
  ::unsetenv("NOTIFY_SOCKET");
  ::setenv("WATCHDOG_USEC", "4000000", 1);
  systemd::ServiceNotifier outside;
  EXPECT_FALSE(outside.active());
  EXPECT_EQ(outside.watchdog_period_ns(), 0);
  outside.ready(0);
  outside.alive(10'000'000'000);
  outside.stopping();
  EXPECT_EQ(outside.watchdog_sent(), 0u);
  EXPECT_EQ(outside.failures(), 0u);

  ::setenv("NOTIFY_SOCKET", "/nonexistent/rankslam-notify", 1);
  systemd::ServiceNotifier inside;
  EXPECT_TRUE(inside.active());
  EXPECT_EQ(inside.watchdog_period_ns(), 2'000'000'000);
  // Another process' watchdog is not this one's.
  ::setenv("WATCHDOG_PID", "1", 1);
  systemd::ServiceNotifier other;
  EXPECT_EQ(other.watchdog_period_ns(), 0);
  ::unsetenv("WATCHDOG_PID");
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("NOTIFY_SOCKET");
}

TEST(ServiceNotifier, TurnsWithoutANotificationAllocateNothing) {
  ::setenv("NOTIFY_SOCKET", "/nonexistent/rankslam-notify", 1);
  ::setenv("WATCHDOG_USEC", "1000000", 1);
  systemd::ServiceNotifier notifier;
  notifier.ready(0);  // to a socket that is not there: a failure
  ASSERT_EQ(notifier.failures(), 1u);
  test_support::CountAllocations count;
  for (std::int64_t t = 0; t < 400'000'000; t += 1'000'000) notifier.alive(t);
  EXPECT_EQ(count.this_thread_allocations(), 0);
  EXPECT_EQ(notifier.watchdog_sent(), 0u);
  EXPECT_EQ(notifier.failures(), 1u);
  notifier.alive(500'000'000);  // a period (0.5 s) on: one notification
  EXPECT_EQ(notifier.failures(), 2u);
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("NOTIFY_SOCKET");
}

TEST(StatusLine, OneLinePerIntervalWithTheChangeSinceTheLastAndNoAllocation) {
  int fds[2];
  ASSERT_EQ(::pipe2(fds, O_CLOEXEC | O_NONBLOCK), 0);
  StatusLine line(60'000'000'000, fds[1]);
  StatusTotals totals;
  totals.counts.tracking = 100;
  line.start(0, totals);
  totals.counts.tracking = 1600;
  totals.counts.degraded = 180;
  totals.counts.lost = 20;
  totals.empty_reads = 7;
  totals.keyframes = 42;
  test_support::CountAllocations count;
  EXPECT_FALSE(line.tick(59'000'000'000, totals));
  EXPECT_TRUE(line.tick(60'000'000'000, totals));
  EXPECT_FALSE(line.tick(61'000'000'000, totals));
  EXPECT_EQ(count.this_thread_allocations(), 0);
  EXPECT_EQ(line.lines(), 1u);
  const std::string text(line.last_line());
  EXPECT_EQ(text.rfind("status: last 60 s: 28.3 frames/s, TRACKING 1500, DEGRADED 180, LOST 20, "
                       "camera reads without a frame 7; key-frames 42, RSS ",
                       0),
            0u)
      << text;
  char written[512];
  const ssize_t n = ::read(fds[0], written, sizeof written);
  ASSERT_GT(n, 0);
  EXPECT_EQ(std::string(written, static_cast<std::size_t>(n)), text + "\n");
  EXPECT_GT(resident_mb(), 1.0);
  ::close(fds[0]);
  ::close(fds[1]);
}

TEST(StatusLine, WithCheckpointsCountsThoseWrittenAndFailedOverTheInterval) {
  int fds[2];
  ASSERT_EQ(::pipe2(fds, O_CLOEXEC | O_NONBLOCK), 0);
  StatusLine line(60'000'000'000, fds[1]);
  StatusTotals totals;
  totals.checkpoints = true;
  totals.checkpoints_written = 5;
  totals.checkpoints_failed = 1;
  line.start(0, totals);
  totals.counts.tracking = 1800;
  totals.checkpoints_written = 6;
  totals.checkpoints_failed = 2;
  test_support::CountAllocations count;
  EXPECT_TRUE(line.tick(60'000'000'000, totals));
  EXPECT_EQ(count.this_thread_allocations(), 0);
  const std::string text(line.last_line());
  EXPECT_NE(text.find(" MB, checkpoints written 1, failed 1"), std::string::npos) << text;
  EXPECT_EQ(text.back(), '1') << text;
  ::close(fds[0]);
  ::close(fds[1]);
}

}  // namespace
}  // namespace rankslam::app
