// Thesis ch. 6 (§6.3.3, table 6.1): RGB-D frames registered to wide-angle frames through nine
// virtual views with the RGB-D camera's intrinsics, against the same registration on one
// undistorted wide image with as many pixels; simulated corridor loop, wide-angle frames paired
// with the RGB-D frame taken at the same time and 1 s and 3 s later. A registration counts as
// correct within 10 cm and 3° of the ground truth. RANKSLAM_WIDE_BENCH_SEEDS (default 1) sets how
// many seeds run (seeds 1..n); RANKSLAM_WIDE_BENCH_STEP (default 6: every sixth wide-angle frame,
// 0.6 s apart, for the suite's time) which wide-angle frames are registered (3: docs/results.md).
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/wide/features.hpp"
#include "rankslam/wide/mono_registrar.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace rankslam::wide {
namespace {

namespace fs = std::filesystem;

constexpr int kFrames = 450;           // 15 s of the corridor loop
constexpr int kOffsets[] = {0, 30, 90};  // RGB-D frames after the wide-angle frame
constexpr double kCorrectM = 0.10;
constexpr double kCorrectDeg = 3.0;
constexpr double kFalseM = 0.25;  // the loop closure's false-edge distance (docs/methods.md §10)

/// The single undistorted image: 1920 × 1440 (nine views' pixels), 140° across.
hal::CameraCalibration single_image() {
  hal::CameraCalibration camera;
  camera.width = 1920;
  camera.height = 1440;
  camera.fx = camera.fy = 960.0 / std::tan(70.0 * M_PI / 180.0);
  camera.cx = 959.5;
  camera.cy = 719.5;
  return camera;
}

struct Tally {
  int pairs = 0;
  int correct = 0;
  int wrong = 0;
  int false_edges = 0;  ///< off by more than kFalseM
  double worst_m = 0.0;
  double inliers_correct = 0.0;
  std::vector<int> inliers;  ///< per pair, 0 unless correct
};

Eigen::Isometry3d nearest_pose(const eval::Trajectory& truth, double stamp) {
  const auto it = std::min_element(truth.begin(), truth.end(), [&](const auto& a, const auto& b) {
    return std::abs(a.stamp_s - stamp) < std::abs(b.stamp_s - stamp);
  });
  return it->T_world_cam;
}

void run_seed(std::uint64_t seed, std::size_t wide_step, Tally& nine_tally, Tally& one_tally) {
  const fs::path dir = fs::temp_directory_path() / ("rankslam_wide_bench_" + std::to_string(::getpid()) + "_" +
                                                    std::to_string(seed));
  fs::remove_all(dir);
  sim::SimulationOptions options;
  options.scene = "corridor-loop";
  options.out_dir = dir;
  options.frames = kFrames;
  options.seed = seed;
  ASSERT_EQ(sim::simulate_recording(options, nullptr), "");
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(dir, recording), "");
  ASSERT_TRUE(recording.calibration.fisheye.has_value());
  ASSERT_TRUE(recording.ground_truth.has_value());
  const auto truth = eval::read_tum_trajectory(*recording.ground_truth);
  ASSERT_TRUE(truth.ok());
  const hal::Calibration& calibration = recording.calibration;
  const Eigen::Isometry3d T_rgb_wide = calibration.rgb.T_base_cam.inverse() * calibration.fisheye->T_base_cam;

  const camera::VirtualViews nine(*calibration.fisheye, calibration.rgb);
  const camera::VirtualViews one(*calibration.fisheye, single_image(), {1, 1, 0.0});
  WideFeatureExtractor nine_extractor(nine);
  SiftOptions one_options;
  one_options.features_per_image = 9 * SiftOptions{}.features_per_image;
  WideFeatureExtractor one_extractor(one, one_options);
  RgbdFeatureExtractor rgbd_extractor{camera::DepthCameraModel(calibration)};
  MonoRegistrar registrar;

  std::map<std::size_t, RgbdFeatures> rgbd_cache;
  const auto rgbd_features = [&](std::size_t index) -> const RgbdFeatures& {
    auto it = rgbd_cache.find(index);
    if (it != rgbd_cache.end()) return it->second;
    const auto& entry = recording.frames[index];
    const cv::Mat image = cv::imread((dir / entry.rgb_file).string(), cv::IMREAD_COLOR);
    const cv::Mat depth = cv::imread((dir / entry.depth_file).string(), cv::IMREAD_UNCHANGED);
    RgbdFeatures features;
    EXPECT_TRUE(rgbd_extractor.extract(image, depth, features)) << entry.rgb_file;
    return rgbd_cache.emplace(index, std::move(features)).first->second;
  };

  for (std::size_t w = 0; w < recording.fisheye.size(); w += wide_step) {
    const auto& wide_entry = recording.fisheye[w];
    const cv::Mat wide = cv::imread((dir / wide_entry.file).string(), cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(wide.empty()) << wide_entry.file;
    WideFeatures nine_features;
    WideFeatures one_features;
    ASSERT_TRUE(nine_extractor.extract(wide, nine_features));
    ASSERT_TRUE(one_extractor.extract(wide, one_features));
    const auto at = std::min_element(recording.frames.begin(), recording.frames.end(), [&](const auto& a, const auto& b) {
      return std::abs(a.rgb_stamp_s - wide_entry.stamp_s) < std::abs(b.rgb_stamp_s - wide_entry.stamp_s);
    });
    const auto base = static_cast<std::size_t>(at - recording.frames.begin());
    const Eigen::Isometry3d T_world_wide = nearest_pose(truth.value(), wide_entry.stamp_s) * T_rgb_wide;
    for (const int offset : kOffsets) {
      const std::size_t index = base + static_cast<std::size_t>(offset);
      if (index >= recording.frames.size()) continue;
      const RgbdFeatures& rgbd = rgbd_features(index);
      const Eigen::Isometry3d truth_T = T_world_wide.inverse() * nearest_pose(truth.value(), recording.frames[index].rgb_stamp_s);
      for (auto* run : {&nine_tally, &one_tally}) {
        const MonoRegistration r = registrar.register_frames(rgbd, run == &nine_tally ? nine_features : one_features);
        ++run->pairs;
        const double t_error = (r.T_wide_rgbd.translation() - truth_T.translation()).norm();
        const double r_error =
            Eigen::AngleAxisd(r.T_wide_rgbd.linear().transpose() * truth_T.linear()).angle() * 180.0 / M_PI;
        const bool correct = r.ok && t_error < kCorrectM && r_error < kCorrectDeg;
        run->correct += correct ? 1 : 0;
        run->wrong += r.ok && !correct ? 1 : 0;
        run->false_edges += r.ok && t_error > kFalseM ? 1 : 0;
        if (r.ok) run->worst_m = std::max(run->worst_m, t_error);
        run->inliers_correct += correct ? r.inliers : 0;
        run->inliers.push_back(correct ? r.inliers : 0);
        if (r.ok && t_error > kFalseM) {
          std::printf("seed %llu wide %.2f s, RGB-D +%d: %s wrong by %.3f m %.1f deg, %d inliers of %d matches\n",
                      static_cast<unsigned long long>(seed), wide_entry.stamp_s - 1700000000.0, offset,
                      run == &nine_tally ? "nine views" : "one image", t_error, r_error, r.inliers, r.matches);
        }
      }
    }
  }
  fs::remove_all(dir);
}

TEST(RgbdMonoRegistration, NineVirtualViewsAgainstOneUndistortedImage) {
  int seeds = 1;
  if (const char* text = std::getenv("RANKSLAM_WIDE_BENCH_SEEDS")) seeds = std::clamp(std::atoi(text), 1, 10);
  int step = 6;
  if (const char* text = std::getenv("RANKSLAM_WIDE_BENCH_STEP")) step = std::clamp(std::atoi(text), 1, 30);
  Tally nine;
  Tally one;
  for (int seed = 1; seed <= seeds; ++seed) {
    const Tally nine_before = nine;
    const Tally one_before = one;
    run_seed(static_cast<std::uint64_t>(seed), static_cast<std::size_t>(step), nine, one);
    if (HasFatalFailure()) return;
    std::printf("seed %d: correct %d / %d with nine views, %d / %d with one image\n", seed,
                nine.correct - nine_before.correct, nine.pairs - nine_before.pairs, one.correct - one_before.correct,
                one.pairs - one_before.pairs);
  }
  double both_nine = 0.0;
  double both_one = 0.0;
  int both = 0;
  for (std::size_t i = 0; i < nine.inliers.size(); ++i) {
    if (nine.inliers[i] == 0 || one.inliers[i] == 0) continue;
    both_nine += nine.inliers[i];
    both_one += one.inliers[i];
    ++both;
  }
  for (const auto* run : {&nine, &one}) {
    std::printf("%s: %d of %d pairs registered correctly (mean %.1f inliers), %d off by more (%d beyond %.2f m, "
                "worst %.3f m)\n",
                run == &nine ? "nine virtual views" : "one undistorted image", run->correct, run->pairs,
                run->correct > 0 ? run->inliers_correct / run->correct : 0.0, run->wrong, run->false_edges, kFalseM,
                run->worst_m);
  }
  std::printf("pairs both register correctly: %d; mean inliers %.1f with nine views, %.1f with one image\n", both,
              both > 0 ? both_nine / both : 0.0, both > 0 ? both_one / both : 0.0);
  // Printed above, not judged: which of the two registers more pairs (docs/results.md §10.2).
  // Judged: the registration through the views works, and accepts no false edge.
  EXPECT_GE(nine.correct, nine.pairs / 5);
  EXPECT_EQ(nine.false_edges, 0);
}

}  // namespace
}  // namespace rankslam::wide
