#include "rankslam/slam/motion_model.hpp"

#include <gtest/gtest.h>

#include <string_view>

namespace rankslam::slam {
namespace {

Eigen::Isometry3d moved_x(double metres) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = metres;
  return T;
}

MotionEstimate estimate_of(const Eigen::Isometry3d& T_target_source, int inliers = 100) {
  MotionEstimate estimate;
  estimate.ok = true;
  estimate.T_target_source = T_target_source;
  estimate.inliers = inliers;
  return estimate;
}

// Tracks one frame 1 cm along x, so the constant-velocity prediction is 1 cm per frame.
void track_one_step(MotionModel& model, Eigen::Isometry3d& T_world_previous) {
  FrameResult result;
  std::string_view reason;
  ASSERT_TRUE(model.accept(estimate_of(moved_x(0.01)), T_world_previous, T_world_previous, model.predicted(nullptr),
                           result.T_world_cam, reason));
  result.status = FrameStatus::kTracking;
  model.finish(T_world_previous, nullptr, result);
  T_world_previous = result.T_world_cam;
}

TEST(MotionModel, AcceptsARegistrationNearThePredictionAndRejectsImplausibleOnes) {
  SlamConfig config;
  MotionModel model(config);
  Eigen::Isometry3d T_world_previous = Eigen::Isometry3d::Identity();
  track_one_step(model, T_world_previous);
  EXPECT_NEAR(model.predicted(nullptr).translation().x(), 0.01, 1e-12);

  Eigen::Isometry3d T_world_current;
  std::string_view reason;
  EXPECT_TRUE(model.accept(estimate_of(moved_x(0.02)), T_world_previous, T_world_previous, model.predicted(nullptr),
                           T_world_current, reason));
  EXPECT_NEAR(T_world_current.translation().x(), 0.03, 1e-12);
  EXPECT_TRUE(reason.empty());

  EXPECT_FALSE(model.accept(estimate_of(moved_x(config.max_step_translation_m + 0.1)), T_world_previous,
                            T_world_previous, model.predicted(nullptr), T_world_current, reason));
  EXPECT_EQ(reason, "implausible frame-to-frame motion");
  reason = {};
  EXPECT_FALSE(model.accept(estimate_of(moved_x(0.01 + config.max_deviation_translation_m + 0.05)), T_world_previous,
                            T_world_previous, model.predicted(nullptr), T_world_current, reason));
  EXPECT_EQ(reason, "motion far from the prediction");
  reason = {};
  EXPECT_FALSE(model.accept(estimate_of(moved_x(0.01), config.min_inliers - 1), T_world_previous, T_world_previous,
                            model.predicted(nullptr), T_world_current, reason));
  EXPECT_EQ(reason, "too few inliers");
}

TEST(MotionModel, FailedFramesExtrapolateThenHoldAndResumingChecksAgainstTheLastMeasuredPose) {
  SlamConfig config;
  config.max_extrapolated_frames = 3;
  MotionModel model(config);
  Eigen::Isometry3d T_world_previous = Eigen::Isometry3d::Identity();
  track_one_step(model, T_world_previous);
  const Eigen::Isometry3d T_world_tracked = T_world_previous;
  EXPECT_FALSE(model.resuming(nullptr));

  for (int failed = 1; failed <= 5; ++failed) {
    FrameResult result;
    result.status = FrameStatus::kFailed;
    model.finish(T_world_previous, nullptr, result);
    const double step = result.T_world_cam.translation().x() - T_world_previous.translation().x();
    EXPECT_NEAR(step, failed <= config.max_extrapolated_frames ? 0.01 : 0.0, 1e-12) << "failed frame " << failed;
    T_world_previous = result.T_world_cam;
  }
  EXPECT_TRUE(model.resuming(nullptr));
  nav::MotionPrior prior;
  EXPECT_FALSE(model.resuming(&prior));

  // Six frames since the last measured pose: up to six deviation gates from it, whatever the
  // extrapolation says; a reference registration needs reference_min_overlap of its inliers.
  Eigen::Isometry3d T_world_current;
  std::string_view reason;
  const Eigen::Isometry3d reachable = moved_x(5.5 * config.max_deviation_translation_m);
  EXPECT_TRUE(model.accept(estimate_of(reachable), T_world_tracked, T_world_previous, model.predicted(nullptr),
                           T_world_current, reason, true, 100));
  EXPECT_FALSE(model.accept(estimate_of(moved_x(6.5 * config.max_deviation_translation_m)), T_world_tracked,
                            T_world_previous, model.predicted(nullptr), T_world_current, reason, true, 100));
  EXPECT_EQ(reason, "motion since the last tracked frame far from any the camera can have made");
  reason = {};
  EXPECT_FALSE(model.accept(estimate_of(reachable, 40), T_world_tracked, T_world_previous, model.predicted(nullptr),
                            T_world_current, reason, true, 100));
  EXPECT_EQ(reason, "too few inliers to resume tracking");

  // A frame that resumed tracking jumped from an extrapolation: the next prediction holds still.
  FrameResult resumed;
  resumed.status = FrameStatus::kTracking;
  resumed.T_world_cam = T_world_tracked * reachable;
  model.set_resumed(true);
  model.finish(T_world_previous, nullptr, resumed);
  EXPECT_TRUE(model.predicted(nullptr).isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(model.resuming(nullptr));
}

TEST(MotionModel, AFrameTheWheelsCarryTakesTheirMotion) {
  SlamConfig config;
  MotionModel model(config);
  nav::MotionPrior prior;
  prior.T_previous_current = moved_x(0.03);
  EXPECT_NEAR(model.predicted(&prior).translation().x(), 0.03, 1e-12);
  FrameResult result;
  result.status = FrameStatus::kWheels;
  model.finish(moved_x(1.0), &prior, result);
  EXPECT_NEAR(result.T_world_cam.translation().x(), 1.03, 1e-12);
  EXPECT_NEAR(model.predicted(nullptr).translation().x(), 0.03, 1e-12);  // the next frame without wheels
}

}  // namespace
}  // namespace rankslam::slam
