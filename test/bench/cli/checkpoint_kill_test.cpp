// Checkpoints under kill -9 (map.checkpoint_s): a child process runs `rankslam run`'s live loop —
// replay camera, frame pipeline, checkpointer and checkpoint writer, as run_command wires them,
// without the CAN output this host has no bus for — starting in the map file the previous child
// left, and is killed with SIGKILL at 20 random moments. After every kill the map file must load,
// its directory must hold nothing else (no temporary file, whole or half-written), and the
// published outputs must be whole; the next start must clear what the killed one staged. The
// same through the real executable on vcan0 is test/vm/checkpoint_test.sh.
#include "checkpointer.hpp"
#include "exit_codes.hpp"
#include "frame_pipeline.hpp"
#include "live_loop.hpp"

#include "rankslam/hal/file_set.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace rankslam::app {
namespace {

namespace fs = std::filesystem;

constexpr const char* kChildEnv = "RANKSLAM_CHECKPOINT_CHILD_DIR";
constexpr double kCheckpointInterval_s = 0.05;

slam::SlamConfig test_config() {
  slam::SlamConfig config;
  config.keyframe_capacity = 32;
  return config;
}

// The child: the live loop with checkpoints until it is killed (it never stops by itself).
TEST(CheckpointKill, DISABLED_Child) {
  const char* dir_text = std::getenv(kChildEnv);
  ASSERT_NE(dir_text, nullptr);
  const fs::path dir = dir_text;
  const fs::path out = dir / "out";
  ASSERT_EQ(hal::prepare_output_directory(out), "");
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(dir / "recording", recording), "");
  replay::ReplayOptions options;
  options.rate = 0.0;  // lossless: as fast as the loop runs
  replay::ReplayDepthCamera camera(recording, options);
  ASSERT_EQ(camera.open(), "");
  const slam::SlamConfig config = test_config();
  PipelineOptions pipeline_options;
  pipeline_options.max_frames = 1000;
  FramePipeline pipeline(config, camera.calibration(), nullptr, pipeline_options);
  const fs::path map_file = dir / "maps" / "map.rsm";
  if (fs::exists(map_file)) {
    ASSERT_EQ(pipeline.load_map(map_file), kExitOk);
  }
  CheckpointWriter writer(config, camera.calibration(), map_file, out, OutputFrame::kCamera,
                          Eigen::Isometry3d::Identity(), "test");
  Checkpointer checkpointer(pipeline.loop(), pipeline_options.max_frames, kCheckpointInterval_s, std::ref(writer));
  nav::PoseMailbox mailbox;
  LiveLoopParts parts;
  parts.camera = &camera;
  parts.replay_camera = &camera;
  parts.pipeline = &pipeline;
  parts.mailbox = &mailbox;
  parts.exit_after_end_s = -1.0;
  parts.checkpointer = &checkpointer;
  std::cout << "loop starts" << std::endl;
  (void)run_live_loop(parts, [] { return false; });
}

std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  if (in) text << in.rdbuf();
  return text.str();
}

std::vector<std::string> names_in(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) names.push_back(entry.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string joined(const std::vector<std::string>& names) {
  std::string text;
  for (const auto& name : names) text += (text.empty() ? "" : " ") + name;
  return text;
}

/// Empty when `path` holds complete TUM lines (8 numbers and a newline each), else why not.
std::string whole_trajectory(const fs::path& path) {
  if (!fs::is_regular_file(path)) return "no file " + path.string();
  const std::string text = read_text(path);
  if (!text.empty() && text.back() != '\n') return "the last line has no newline";
  std::istringstream lines(text);
  std::string line;
  while (std::getline(lines, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double value = 0.0;
    int count = 0;
    while (fields >> value) ++count;
    if (count != 8 || !fields.eof()) return "line '" + line + "'";
  }
  return {};
}

TEST(CheckpointKill, TheLastCheckpointAlwaysLoadsAndNothingIsLeftHalfWritten) {
  const fs::path dir = fs::temp_directory_path() / ("rankslam-checkpoint-kill-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "maps");
  sim::SimulationOptions simulation;
  simulation.scene = "corridor-loop";
  simulation.out_dir = dir / "recording";
  simulation.frames = 200;
  ASSERT_EQ(sim::simulate_recording(simulation, nullptr), "");
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(simulation.out_dir, recording), "");
  const hal::Calibration calibration = recording.calibration;
  const slam::SlamConfig config = test_config();
  slam::SlamLoop checker(config, calibration);

  const char* seed_text = std::getenv("RANKSLAM_KILL_SEED");
  const auto seed = seed_text != nullptr ? std::strtoull(seed_text, nullptr, 10)
                                         : static_cast<unsigned long long>(std::chrono::system_clock::now().time_since_epoch().count());
  std::mt19937_64 random(seed);
  std::uniform_int_distribution<int> moment_ms(0, 1500);
  std::cout << "RANKSLAM_KILL_SEED=" << seed << std::endl;

  const std::string self = fs::read_symlink("/proc/self/exe").string();
  const std::string env_entry = std::string(kChildEnv) + "=" + dir.string();
  int with_map = 0;
  std::set<std::string> checkpoint_frames;
  constexpr int kKills = 20;
  for (int kill_index = 1; kill_index <= kKills; ++kill_index) {
    const fs::path log = dir / ("child-" + std::to_string(kill_index) + ".log");
    std::vector<std::string> args = {self, "--gtest_filter=CheckpointKill.DISABLED_Child", "--gtest_also_run_disabled_tests"};
    std::vector<char*> argv;
    for (auto& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    std::vector<std::string> env_strings;
    for (char** e = environ; *e != nullptr; ++e) env_strings.emplace_back(*e);
    env_strings.push_back(env_entry);
    std::vector<char*> envp;
    for (auto& entry : env_strings) envp.push_back(entry.data());
    envp.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    pid_t child = 0;
    ASSERT_EQ(posix_spawn(&child, self.c_str(), &actions, nullptr, argv.data(), envp.data()), 0);
    posix_spawn_file_actions_destroy(&actions);

    // The moment counts from the start of the loop: set-up is the same every time.
    const auto started = std::chrono::steady_clock::now();
    bool looping = false;
    while (!looping && std::chrono::steady_clock::now() - started < std::chrono::seconds(60)) {
      looping = read_text(log).find("loop starts") != std::string::npos;
      if (!looping) std::this_thread::sleep_for(std::chrono::milliseconds(10));
      int status = 0;
      if (::waitpid(child, &status, WNOHANG) == child) FAIL() << "the child ended by itself; its log: " << log;
    }
    ASSERT_TRUE(looping) << "the child did not start its loop; its log: " << log;
    const int ms = moment_ms(random);
    std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    ASSERT_EQ(::kill(child, SIGKILL), 0);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the child ended by itself before the kill; its log: " << log;

    const std::string what = "kill " + std::to_string(kill_index) + " at " + std::to_string(ms) + " ms";
    const std::vector<std::string> maps = names_in(dir / "maps");
    const fs::path map_file = dir / "maps" / "map.rsm";
    if (fs::exists(map_file)) {
      ++with_map;
      EXPECT_EQ(joined(maps), "map.rsm") << what << ": the map directory holds more than the map";
      try {
        (void)checker.load_map(map_file);
      } catch (const std::exception& error) {
        ADD_FAILURE() << what << ": " << error.what();
      }
    } else {
      EXPECT_TRUE(maps.empty()) << what << ": no map, but the map directory holds " << joined(maps);
    }
    const fs::path out = dir / "out";
    if (fs::exists(out / "trajectory.txt")) {
      EXPECT_EQ(whole_trajectory(out / "trajectory.txt"), "") << what;
      const std::string text = read_text(out / "report.json");
      std::smatch frames;
      EXPECT_TRUE(std::regex_search(text, frames, std::regex("\"frames\": ([0-9]+)"))) << what << ": report.json " << text;
      if (!frames.empty()) checkpoint_frames.insert(frames[1]);
      EXPECT_TRUE(fs::exists(out / "map.ply")) << what;
    }
    std::cout << what << ": map directory [" << joined(maps) << "], outputs [" << joined(names_in(out)) << "]" << std::endl;
  }
  // What the last killed process staged goes at the next start; the published set stays.
  ASSERT_EQ(hal::prepare_output_directory(dir / "out"), "");
  const std::vector<std::string> left = names_in(dir / "out");
  int sets = 0;
  for (const auto& name : left) sets += name.rfind("set-", 0) == 0 ? 1 : 0;
  EXPECT_LE(sets, 1) << joined(left);

  std::cout << with_map << " of " << kKills << " kills left a map file; checkpoints published at "
            << checkpoint_frames.size() << " different frames" << std::endl;
  EXPECT_GE(with_map, kKills / 2) << "too few kills came after a checkpoint for the test to test";
  EXPECT_GE(checkpoint_frames.size(), 3U) << "the checkpoints were published at too few moments";
  if (!HasFailure()) fs::remove_all(dir);
}

}  // namespace
}  // namespace rankslam::app
