#include "rankslam/slam/slam_loop.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <random>

namespace rankslam::slam {
namespace {

constexpr double kFx = 500.0;
constexpr double kPlaneDepth_m = 2.0;

hal::Calibration pinhole() {
  hal::Calibration calibration;
  calibration.rgb.fx = calibration.rgb.fy = kFx;
  calibration.rgb.cx = 319.5;
  calibration.rgb.cy = 239.5;
  return calibration;
}

// A textured wall 2 m in front of the camera: moving the camera sideways by s pixels' worth
// (s·z/f metres) shifts the view of the texture by s pixels.
class WallSequence {
 public:
  WallSequence() : texture_(480 + 200, 640 + 400, CV_8UC3) {
    std::mt19937 rng(3);
    cv::Mat noise(texture_.rows / 4, texture_.cols / 4, CV_8UC3);
    cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
    cv::resize(noise, texture_, texture_.size(), 0, 0, cv::INTER_CUBIC);
    cv::GaussianBlur(texture_, texture_, cv::Size(3, 3), 0.8);
  }

  hal::RgbdFrame frame(int shift_px, std::uint32_t sequence) {
    hal::RgbdFrame frame;
    frame.sequence = sequence;
    frame.stamp_s = sequence / 30.0;
    frame.rgb = texture_(cv::Rect(200 + shift_px, 100, 640, 480)).clone();
    frame.depth = cv::Mat(480, 640, CV_16UC1, cv::Scalar(kPlaneDepth_m * 5000.0));
    return frame;
  }

  static double metres(int shift_px) { return shift_px * kPlaneDepth_m / kFx; }

 private:
  cv::Mat texture_;
};

class SlamLoopModes : public ::testing::TestWithParam<Mode> {};

TEST_P(SlamLoopModes, TracksASidewaysMotionAlongATexturedWall) {
  SlamConfig config;
  config.mode = GetParam();
  SlamLoop loop(config, pinhole());
  WallSequence wall;
  FrameResult result;
  for (int i = 0; i <= 20; ++i) {
    result = loop.process(wall.frame(4 * i, static_cast<std::uint32_t>(i)));
    if (i == 0) {
      EXPECT_EQ(result.status, FrameStatus::kFirstFrame);
      EXPECT_TRUE(result.keyframe);
    } else {
      ASSERT_EQ(result.status, FrameStatus::kTracking) << "frame " << i << ": " << result.failure_reason;
      // MSSE keeps a smaller core than a 2 cm RANSAC on noise-free synthetic images (the
      // scale estimate is tiny); the pose below is what must be right.
      EXPECT_GE(result.inliers, config.min_inliers) << "frame " << i;
    }
  }
  // The texture moves left in the image as the camera moves right (+x).
  EXPECT_NEAR(result.T_world_cam.translation().x(), WallSequence::metres(80), 0.01);
  EXPECT_NEAR(result.T_world_cam.translation().y(), 0.0, 0.01);
  EXPECT_NEAR(result.T_world_cam.translation().z(), 0.0, 0.01);
  EXPECT_LT(Eigen::AngleAxisd(result.T_world_cam.rotation()).angle(), 0.01);
  EXPECT_GT(loop.keyframes(), 1);
  EXPECT_GT(loop.map().size(), 1000U);
}

TEST_P(SlamLoopModes, FailedFramesPropagateAtConstantVelocityAndStayFinite) {
  SlamConfig config;
  config.mode = GetParam();
  SlamLoop loop(config, pinhole());
  WallSequence wall;
  FrameResult result;
  for (int i = 0; i < 5; ++i) result = loop.process(wall.frame(4 * i, static_cast<std::uint32_t>(i)));
  ASSERT_EQ(result.status, FrameStatus::kTracking);
  const double speed_m = WallSequence::metres(4);

  // A blank frame (lens covered): nothing to match.
  hal::RgbdFrame blank = wall.frame(20, 5);
  blank.rgb.setTo(cv::Scalar::all(0));
  result = loop.process(blank);
  EXPECT_EQ(result.status, FrameStatus::kFailed);
  EXPECT_FALSE(result.failure_reason.empty());
  EXPECT_TRUE(result.T_world_cam.matrix().allFinite());
  EXPECT_NEAR(result.T_world_cam.translation().x(), 5 * speed_m, 0.005);

  // No depth at all.
  hal::RgbdFrame no_depth = wall.frame(24, 6);
  no_depth.depth.setTo(cv::Scalar(0));
  result = loop.process(no_depth);
  EXPECT_EQ(result.status, FrameStatus::kFailed);
  EXPECT_NEAR(result.T_world_cam.translation().x(), 6 * speed_m, 0.005);
}

INSTANTIATE_TEST_SUITE_P(Modes, SlamLoopModes, ::testing::Values(Mode::kBaseline, Mode::kPhotometric),
                         [](const auto& param_info) { return std::string(to_string(param_info.param)); });

}  // namespace
}  // namespace rankslam::slam
