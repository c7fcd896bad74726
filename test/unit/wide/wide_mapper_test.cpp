// wide::WideMapper on the simulated corridor loop: a key-frame's SIFT features are kept in its
// slot, a later key-frame's wide-angle image registers to them on the mapper's thread (chosen by
// VLAD over a key-frame of another scene), and the edge found agrees with the ground truth;
// stale candidates and wrong images are refused.
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/wide/wide_mapper.hpp"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>

namespace rankslam::wide {
namespace {

namespace fs = std::filesystem;

class WideMapperTest : public ::testing::Test {
 protected:
  // OpenCV's SIFT otherwise fans out over TBB's workers, whose hand-offs ThreadSanitizer cannot
  // see (TBB is not instrumented); what is tested here is the mapper's own thread and queue.
  static void SetUpTestSuite() { cv::setNumThreads(1); }

  /// The first `frames` of the corridor loop and their ground truth (simulating is what costs:
  /// each test asks only for the frames it reads).
  void prepare(int frames) {
    dir_ = fs::temp_directory_path() / ("rankslam_wide_mapper_" + std::to_string(::getpid()));
    simulate("corridor-loop", frames, dir_, recording_);
    ASSERT_TRUE(recording_.calibration.fisheye.has_value());
    ASSERT_TRUE(recording_.ground_truth.has_value());
    auto truth = eval::read_tum_trajectory(*recording_.ground_truth);
    ASSERT_TRUE(truth.ok());
    truth_ = std::move(truth).value();
  }
  void TearDown() override {
    if (!dir_.empty()) fs::remove_all(dir_);
  }

  /// `frames` of `scene` (seed 1) simulated into `dir`, indexed into `recording`.
  static void simulate(const std::string& scene, int frames, const fs::path& dir, replay::Recording& recording) {
    fs::remove_all(dir);
    sim::SimulationOptions options;
    options.scene = scene;
    options.out_dir = dir;
    options.frames = frames;
    options.seed = 1;
    ASSERT_EQ(sim::simulate_recording(options, nullptr), "");
    ASSERT_EQ(replay::open_recording(dir, recording), "");
  }

  /// Frame `index`'s colour, depth and the wide-angle image nearest it.
  void load(std::size_t index, cv::Mat& colour, cv::Mat& depth, cv::Mat& wide) const {
    const auto& entry = recording_.frames.at(index);
    colour = cv::imread((dir_ / entry.rgb_file).string(), cv::IMREAD_COLOR);
    depth = cv::imread((dir_ / entry.depth_file).string(), cv::IMREAD_UNCHANGED);
    const auto nearest = std::min_element(recording_.fisheye.begin(), recording_.fisheye.end(), [&](const auto& a, const auto& b) {
      return std::abs(a.stamp_s - entry.rgb_stamp_s) < std::abs(b.stamp_s - entry.rgb_stamp_s);
    });
    ASSERT_LT(std::abs(nearest->stamp_s - entry.rgb_stamp_s), 0.02);
    wide = cv::imread((dir_ / nearest->file).string(), cv::IMREAD_COLOR);
  }
  [[nodiscard]] Eigen::Isometry3d truth_at(std::size_t index) const {
    const double stamp = recording_.frames.at(index).rgb_stamp_s;
    return std::min_element(truth_.begin(), truth_.end(), [&](const auto& a, const auto& b) {
             return std::abs(a.stamp_s - stamp) < std::abs(b.stamp_s - stamp);
           })->T_world_cam;
  }

  fs::path dir_;
  replay::Recording recording_;
  eval::Trajectory truth_;
};

WideResult run(WideMapper& mapper, const WideSubmission& submission) {
  EXPECT_TRUE(mapper.submit(submission));
  mapper.wait_idle();
  WideResult out;
  int results = 0;
  mapper.take_results([&](const WideResult& result) {
    out = result;
    ++results;
  });
  EXPECT_EQ(results, 1);
  return out;
}

TEST_F(WideMapperTest, RegistersALaterKeyFramesImageToAStoredOne) {
  ASSERT_NO_FATAL_FAILURE(prepare(34));
  WideMapperOptions options;
  options.capacity = 4;
  WideMapper mapper(recording_.calibration, options);
  // Key-frame A: frame 0, its colour and depth kept in slot 0. Key-frame O, in slot 2: a frame
  // of another scene (the simulated office). Key-frame B: frame 30 (1 s on), whose image comes
  // with frame 33, tracked from it.
  cv::Mat colour_a, depth_a, wide_a, colour_b, depth_b, wide_b;
  load(0, colour_a, depth_a, wide_a);
  load(33, colour_b, depth_b, wide_b);
  WideSubmission a{&colour_a, &depth_a, &wide_a, {0, 1}, Eigen::Isometry3d::Identity(), {}, {}, 0};
  const WideResult first = run(mapper, a);
  EXPECT_EQ(first.keyframe.slot, 0);
  EXPECT_GT(first.rgbd_features, 100);
  EXPECT_GT(first.wide_features, 1000);
  EXPECT_EQ(first.tried, 0);

  const fs::path office_dir = dir_.string() + "_office";
  replay::Recording office;
  simulate("office", 2, office_dir, office);
  const cv::Mat colour_o = cv::imread((office_dir / office.frames.at(0).rgb_file).string(), cv::IMREAD_COLOR);
  const cv::Mat depth_o = cv::imread((office_dir / office.frames.at(0).depth_file).string(), cv::IMREAD_UNCHANGED);
  fs::remove_all(office_dir);
  EXPECT_GT(run(mapper, {&colour_o, &depth_o, &wide_a, {2, 2}, Eigen::Isometry3d::Identity(), {}, {}, 0}).rgbd_features, 100);

  // B's image is offered the stale candidates (slots reused or empty) and, by place
  // recognition, one of the office key-frame (listed first) and A: VLAD must choose A.
  const Eigen::Isometry3d T_b_frame = truth_at(30).inverse() * truth_at(33);
  const WideCandidate candidates[] = {{0, 7}, {3, 1}};
  const WideCandidate places[] = {{2, 2}, {0, 1}};
  WideSubmission b{&colour_b, &depth_b, &wide_b, {1, 3}, T_b_frame, candidates, places, 1};
  const WideResult second = run(mapper, b);
  EXPECT_EQ(second.tried, 1);
  ASSERT_EQ(second.edge_count, 1);
  const WideEdge& edge = second.edges[0];
  EXPECT_EQ(edge.stored.slot, 0);
  EXPECT_GT(edge.similarity, 0.0F);
  EXPECT_LE(edge.similarity, 1.0F + 1e-5F);
  EXPECT_GE(edge.inliers, options.registration.min_inliers);
  const Eigen::Isometry3d truth = truth_at(30).inverse() * truth_at(0);
  EXPECT_LT((edge.T_keyframe_stored.translation() - truth.translation()).norm(), 0.1);
  EXPECT_LT(Eigen::AngleAxisd(edge.T_keyframe_stored.linear().transpose() * truth.linear()).angle() * 180.0 / M_PI, 3.0);
  // The information is a covariance's inverse: symmetric, positive definite.
  EXPECT_LT((edge.information - edge.information.transpose()).norm(), 1e-9 * edge.information.norm());
  using Matrix6d = Eigen::Matrix<double, 6, 6>;
  EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix6d>(edge.information).eigenvalues().minCoeff(), 0.0);

  const WideMapperCounters counters = mapper.counters();
  EXPECT_EQ(counters.submitted, 3U);
  EXPECT_EQ(counters.done, 3U);
  EXPECT_EQ(counters.dropped, 0U);
}

TEST_F(WideMapperTest, RefusesImagesOfAnotherSize) {
  ASSERT_NO_FATAL_FAILURE(prepare(1));
  WideMapper mapper(recording_.calibration, {});
  cv::Mat colour, depth, wide;
  load(0, colour, depth, wide);
  const cv::Mat small(wide.rows / 2, wide.cols / 2, CV_8UC3, cv::Scalar::all(0));
  const cv::Mat depth_8u(depth.size(), CV_8UC1, cv::Scalar::all(0));
  EXPECT_FALSE(mapper.submit({&colour, &depth, &small, {0, 1}, Eigen::Isometry3d::Identity(), {}, {}, 0}));
  EXPECT_FALSE(mapper.submit({&colour, &depth_8u, &wide, {0, 1}, Eigen::Isometry3d::Identity(), {}, {}, 0}));
  EXPECT_FALSE(mapper.submit({&colour, &depth, &wide, {-1, 1}, Eigen::Isometry3d::Identity(), {}, {}, 0}));
  EXPECT_EQ(mapper.counters().dropped, 3U);
  EXPECT_EQ(mapper.counters().submitted, 0U);
}

TEST(WideMapper, NeedsTheWideAngleCamerasCalibration) {
  hal::Calibration calibration;
  calibration.rgb.width = 640;
  calibration.rgb.height = 480;
  EXPECT_THROW(WideMapper(calibration, {}), std::invalid_argument);
}

}  // namespace
}  // namespace rankslam::wide
