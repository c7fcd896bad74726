// Accuracy bounds of the photometric visual odometry (issue acceptance): TUM fr1_rpy_head and
// fr1_desk_9 from the shared data, and the simulated dark office, whose recording is written on
// the fly.
#include "rankslam/eval/metrics.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

namespace rankslam::slam {
namespace {

namespace fs = std::filesystem;

struct OdometryRun {
  std::string error;  ///< empty when the run completed
  double ate_m = 0.0;
  int frames = 0;
  int failed = 0;
  int infrared = 0;
};

OdometryRun run_odometry(const fs::path& recording_dir, const SlamConfig& config) {
  OdometryRun run;
  replay::Recording recording;
  if (auto error = replay::open_recording(recording_dir, recording); !error.empty()) {
    run.error = error;
    return run;
  }
  if (!recording.ground_truth) {
    run.error = recording_dir.string() + " has no ground truth";
    return run;
  }
  replay::ReplayDepthCamera camera(recording, {});
  if (auto error = camera.open(); !error.empty()) {
    run.error = error;
    return run;
  }
  SlamLoop loop(config, recording.calibration);
  eval::Trajectory estimate;
  hal::RgbdFrame frame;
  while (camera.read(frame, std::chrono::milliseconds(5000)) == hal::ReadStatus::kOk) {
    const FrameResult result = loop.process(frame);
    estimate.push_back({frame.stamp_s, result.T_world_cam});
    ++run.frames;
    if (result.status == FrameStatus::kFailed) ++run.failed;
    if (result.image_source == ImageSource::kInfrared) ++run.infrared;
  }
  auto ground_truth = eval::read_tum_trajectory(*recording.ground_truth);
  if (!ground_truth) {
    run.error = ground_truth.error();
    return run;
  }
  auto ate = eval::compute_ate(ground_truth.value(), estimate);
  if (!ate) {
    run.error = ate.error();
    return run;
  }
  run.ate_m = ate.value().translation_m.rmse;
  return run;
}

SlamConfig config_for(Mode mode) {
  SlamConfig config;
  config.mode = mode;
  return config;
}

fs::path tum(const char* sequence) { return fs::path(RANKSLAM_SHARED_DATA) / "tum" / sequence; }

TEST(PhotometricOdometryBench, Fr1RpyHeadWithinThreeCentimetres) {
  if (!fs::is_directory(tum("fr1_rpy_head"))) GTEST_SKIP() << "no shared data at " << tum("fr1_rpy_head");
  const OdometryRun photometric = run_odometry(tum("fr1_rpy_head"), config_for(Mode::kPhotometric));
  ASSERT_TRUE(photometric.error.empty()) << photometric.error;
  const OdometryRun baseline = run_odometry(tum("fr1_rpy_head"), config_for(Mode::kBaseline));
  ASSERT_TRUE(baseline.error.empty()) << baseline.error;
  std::printf("fr1_rpy_head: photometric (MSSE) ATE %.4f m, %d failed; baseline (RANSAC) ATE %.4f m, %d failed\n",
              photometric.ate_m, photometric.failed, baseline.ate_m, baseline.failed);
  EXPECT_EQ(photometric.frames, 180);
  EXPECT_LE(photometric.ate_m, 0.030);
  EXPECT_EQ(photometric.failed, 0);
  EXPECT_EQ(photometric.infrared, 0);
  // The baseline is printed, not compared: one seed decides too much between the two (over
  // seeds 1-6 MSSE averaged 0.028 m, RANSAC 0.038 m, yet seed 1 gives RANSAC 0.027 m).
}

TEST(PhotometricOdometryBench, Fr1Desk9WithinOneCentimetre) {
  if (!fs::is_directory(tum("fr1_desk_9"))) GTEST_SKIP() << "no shared data at " << tum("fr1_desk_9");
  const OdometryRun photometric = run_odometry(tum("fr1_desk_9"), config_for(Mode::kPhotometric));
  ASSERT_TRUE(photometric.error.empty()) << photometric.error;
  std::printf("fr1_desk_9: photometric ATE %.4f m\n", photometric.ate_m);
  EXPECT_EQ(photometric.frames, 9);
  EXPECT_LE(photometric.ate_m, 0.010);
  EXPECT_EQ(photometric.failed, 0);
}

// One simulated dark-office recording shared by the tests below.
class DarkOfficeBench : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    directory_ = new fs::path(fs::temp_directory_path() /
                              ("rankslam_bench_dark_office_" + std::to_string(::getpid())));
    fs::remove_all(*directory_);
    sim::SimulationOptions options;
    options.scene = "dark-office";
    options.out_dir = *directory_;
    options.frames = 90;  // 3 s of the hand-held motion
    options.seed = 1;
    sim::SimulationSummary summary;
    error_ = new std::string(sim::simulate_recording(options, &summary));
    if (error_->empty()) std::printf("simulated dark-office: %d frames, %.1f frames/s\n", summary.frames_written, summary.frames_per_second);
  }
  static void TearDownTestSuite() {
    std::error_code ignored;
    fs::remove_all(*directory_, ignored);
    delete directory_;
    delete error_;
  }

  static fs::path* directory_;
  static std::string* error_;
};

fs::path* DarkOfficeBench::directory_ = nullptr;
std::string* DarkOfficeBench::error_ = nullptr;

TEST_F(DarkOfficeBench, InfraredFeaturesTrackWhereColourFails) {
  ASSERT_TRUE(error_->empty()) << *error_;
  const OdometryRun infrared = run_odometry(*directory_, config_for(Mode::kPhotometric));
  ASSERT_TRUE(infrared.error.empty()) << infrared.error;
  SlamConfig colour_only = config_for(Mode::kPhotometric);
  colour_only.ir_switch_brightness = 0.0;
  const OdometryRun colour = run_odometry(*directory_, colour_only);
  ASSERT_TRUE(colour.error.empty()) << colour.error;
  std::printf("dark-office: IR path ATE %.4f m (%d/%d frames on IR, %d failed); colour only ATE %.4f m (%d failed)\n",
              infrared.ate_m, infrared.infrared, infrared.frames, infrared.failed, colour.ate_m, colour.failed);

  EXPECT_EQ(infrared.infrared, infrared.frames);
  EXPECT_EQ(infrared.failed, 0);
  EXPECT_LE(infrared.ate_m, 0.03);
  EXPECT_EQ(colour.infrared, 0);
  const bool colour_fails = 2 * colour.failed > colour.frames;
  EXPECT_TRUE(colour_fails || colour.ate_m >= 3.0 * infrared.ate_m)
      << "colour only: " << colour.failed << " of " << colour.frames << " frames failed, ATE " << colour.ate_m;
}

}  // namespace
}  // namespace rankslam::slam
