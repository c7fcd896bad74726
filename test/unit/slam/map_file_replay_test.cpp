// SlamLoop::save_map / load_map on a short replay of the simulated office (fused mode, so the
// key-frames carry ORB and SHOT features): the loaded loop holds the same key-frames, features
// and graph, and saving it again gives the same bytes.
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace rankslam::slam {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 12;

std::vector<char> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

SlamConfig short_replay_config() {
  SlamConfig config;
  config.mode = Mode::kFused;
  // A key-frame every few frames of the hand-held motion, so a dozen frames make several.
  config.keyframe_translation_m = 0.02;
  config.keyframe_rotation_deg = 2.0;
  config.keyframe_capacity = 16;
  return config;
}

TEST(MapFileReplay, SaveLoadSaveOfTheOfficeIsIdentical) {
  const fs::path dir = fs::temp_directory_path() / ("rankslam_map_file_office_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  sim::SimulationOptions options;
  options.scene = "office";
  options.out_dir = dir / "office";
  options.frames = kFrames;
  options.seed = 1;
  ASSERT_EQ(sim::simulate_recording(options, nullptr), "");
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(options.out_dir, recording), "");

  const SlamConfig config = short_replay_config();
  SlamLoop loop(config, recording.calibration);
  loop.set_synchronous_backend(true);
  {
    replay::ReplayDepthCamera camera(recording, {});
    ASSERT_EQ(camera.open(), "");
    hal::RgbdFrame frame;
    while (camera.read(frame, std::chrono::milliseconds(5000)) == hal::ReadStatus::kOk) (void)loop.process(frame);
  }
  loop.finish();
  ASSERT_GE(loop.keyframe_store().size(), 3);
  const fs::path first = dir / "first.map";
  ASSERT_EQ(loop.save_map(first), "");

  SlamLoop loaded(config, recording.calibration);
  const MapFileInfo info = loaded.load_map(first);
  EXPECT_EQ(info.keyframes, loop.keyframe_store().size());
  EXPECT_EQ(info.edges, loop.pose_graph().edge_count());
  for (int slot = 0; slot < config.keyframe_capacity; ++slot) {
    const StoredKeyframe& a = loop.keyframe_store().slot(slot);
    const StoredKeyframe& b = loaded.keyframe_store().slot(slot);
    ASSERT_EQ(a.used, b.used) << "slot " << slot;
    if (!a.used) continue;
    EXPECT_EQ(a.T_world_cam.matrix(), b.T_world_cam.matrix());
    EXPECT_EQ(a.sequence, b.sequence);
    EXPECT_EQ(a.node, b.node);
    EXPECT_GT(a.photometric.size(), 0U);
    EXPECT_EQ(a.photometric.points_cam, b.photometric.points_cam);
    EXPECT_EQ(cv::norm(a.photometric.descriptors, b.photometric.descriptors, cv::NORM_HAMMING), 0.0);
    EXPECT_GT(a.geometric.count, 0);
    EXPECT_EQ(a.geometric.count, b.geometric.count);
    EXPECT_EQ(a.geometric.codes, b.geometric.codes);
    EXPECT_EQ(a.geometric.scales, b.geometric.scales);
    EXPECT_EQ(a.geometric.cloud_count, b.geometric.cloud_count);
    EXPECT_EQ(a.point_count, b.point_count);
  }
  EXPECT_EQ(loaded.pose_graph().node_count(), loop.pose_graph().node_count());
  EXPECT_EQ(loaded.pose_graph().cost(), loop.pose_graph().cost());
  EXPECT_EQ(loaded.loop_threshold(), loop.loop_threshold());
  EXPECT_GT(loaded.map().size(), 0U);

  const fs::path second = dir / "second.map";
  ASSERT_EQ(loaded.save_map(second), "");
  EXPECT_EQ(read_bytes(second), read_bytes(first));

  // Another camera's map is refused by name, and the refused loop holds no map.
  hal::Calibration other = recording.calibration;
  other.rgb.fx += 1.0;
  SlamLoop elsewhere(config, other);
  try {
    (void)elsewhere.load_map(first);
    ADD_FAILURE() << "a map of another calibration was loaded";
  } catch (const std::runtime_error& error) {
    EXPECT_NE(std::string(error.what()).find(first.string() + ": made with another calibration"), std::string::npos)
        << error.what();
  }
  EXPECT_EQ(elsewhere.keyframe_store().size(), 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rankslam::slam
