// The SLAM loop with a wheel-odometry prior: the prior as prediction and fallback, and the
// comparison of registrations with it (a slipping wheel overruled by vision, vision errors by
// the wheels).
#include "rankslam/slam/slam_loop.hpp"
#include "wall_sequence.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace rankslam::slam {
namespace {

// The camera 0.2 m ahead of the base origin, 0.5 m up, looking forward along the base's x axis:
// camera x = −base y, camera y = −base z, camera z = base x.
Eigen::Isometry3d camera_on_base() {
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  T_base_cam.linear() << 0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0;
  T_base_cam.translation() = Eigen::Vector3d(0.2, 0.0, 0.5);
  return T_base_cam;
}

// The wall sequence's camera on that base: the loop compares vision and wheels in base terms.
hal::Calibration pinhole_on_base() {
  hal::Calibration calibration = pinhole();
  calibration.rgb.T_base_cam = camera_on_base();
  return calibration;
}

// Wheel noise over one frame: 1 mm in x and y, 0.26 deg in yaw.
Eigen::Matrix3d frame_covariance() { return Eigen::Vector3d(1e-6, 1e-6, 2e-5).asDiagonal(); }

// The wall sequence moves the camera along its x axis, which is the base's −y: a base that
// slides sideways (the prior does not need a drivable motion).
nav::MotionPrior sideways_prior(double camera_right_m, double yaw_rad = 0.0) {
  return nav::camera_motion_prior(0.0, -camera_right_m, yaw_rad, frame_covariance(), camera_on_base());
}

class SlamLoopWheels : public ::testing::TestWithParam<Mode> {
 protected:
  SlamConfig config() const {
    SlamConfig config;
    config.mode = GetParam();
    return config;
  }
  // Noise-free synthetic images register far better than a real scene.
  SlamConfig synthetic_vision_config() const {
    SlamConfig slam_config = config();
    slam_config.wheels.vision_sigma_m = 0.005;
    slam_config.wheels.vision_sigma_deg = 0.3;
    return slam_config;
  }
  WallSequence wall_;
  const double speed_m_ = WallSequence::metres(4);
};

TEST_P(SlamLoopWheels, AgreeingWheelsPredictAndVisionKeepsThePose) {
  SlamLoop loop(config(), pinhole_on_base());
  FrameResult result;
  const nav::MotionPrior prior = sideways_prior(speed_m_);
  for (int i = 0; i <= 20; ++i) {
    result = loop.process(wall_.frame(4 * i, static_cast<std::uint32_t>(i)), &prior);
    EXPECT_TRUE(result.wheels.prior_given);
    if (i == 0) continue;
    ASSERT_EQ(result.status, FrameStatus::kTracking) << "frame " << i << ": " << result.failure_reason;
    EXPECT_TRUE(result.wheels.compared);
    EXPECT_FALSE(result.wheels.disagree) << "frame " << i << ": " << result.wheels.frame_distance_sq << " / "
                                         << result.wheels.window_distance_sq;
  }
  EXPECT_NEAR(result.T_world_cam.translation().x(), WallSequence::metres(80), 0.01);
  EXPECT_EQ(loop.wheel_slip_events(), 0);
}

TEST_P(SlamLoopWheels, BlankFramesFollowTheWheelsForAsLongAsTheyLast) {
  SlamConfig slam_config = config();
  slam_config.max_extrapolated_frames = 5;  // without wheels the pose would hold after 5 frames
  SlamLoop loop(slam_config, pinhole_on_base());
  const nav::MotionPrior prior = sideways_prior(speed_m_);
  FrameResult result;
  for (int i = 0; i < 5; ++i) result = loop.process(wall_.frame(4 * i, static_cast<std::uint32_t>(i)), &prior);
  ASSERT_EQ(result.status, FrameStatus::kTracking);
  const double x_before = result.T_world_cam.translation().x();

  hal::RgbdFrame blank = wall_.frame(0, 0);
  blank.rgb.setTo(cv::Scalar::all(0));
  for (int i = 5; i < 45; ++i) {
    blank.sequence = static_cast<std::uint32_t>(i);
    blank.stamp_s = i / 30.0;
    result = loop.process(blank, &prior);
    ASSERT_EQ(result.status, FrameStatus::kWheels) << "frame " << i;
    EXPECT_FALSE(result.failure_reason.empty());
    EXPECT_FALSE(result.wheels.compared);
    EXPECT_NEAR(result.T_world_cam.translation().x(), x_before + (i - 4) * speed_m_, 1e-6) << "frame " << i;
  }
  // The texture again: the reference is still there and tracking resumes at the true pose.
  result = loop.process(wall_.frame(4 * 45, 45), &prior);
  EXPECT_EQ(result.status, FrameStatus::kTracking) << result.failure_reason;
  EXPECT_NEAR(result.T_world_cam.translation().x(), WallSequence::metres(4 * 45), 0.01);
}

TEST_P(SlamLoopWheels, ASlippingWheelGivesThePoseToVisionAndCountsOneEventPerSlip) {
  SlamConfig slam_config = synthetic_vision_config();
  SlamLoop loop(slam_config, pinhole_on_base());
  const nav::MotionPrior good = sideways_prior(speed_m_);
  // One wheel over-counting: 0.6 deg of yaw per frame that the camera never turned.
  const nav::MotionPrior slipping = sideways_prior(speed_m_, 0.6 * M_PI / 180.0);
  FrameResult result;
  int frame = 0;
  struct Counts {
    int slip_shaped = 0;
    int vision_trusted = 0;
  };
  const auto drive = [&](const nav::MotionPrior& prior, int frames) {
    Counts counts;
    for (int k = 0; k < frames; ++k, ++frame) {
      result = loop.process(wall_.frame(4 * frame, static_cast<std::uint32_t>(frame)), &prior);
      if (frame == 0) continue;
      EXPECT_TRUE(result.wheels.compared) << "frame " << frame << ": " << result.failure_reason;
      if (result.wheels.slip_shaped) ++counts.slip_shaped;
      if (result.wheels.vision_trusted) {
        ++counts.vision_trusted;
        EXPECT_EQ(result.status, FrameStatus::kTracking) << "frame " << frame;
      }
      // Across the drive direction, in height and in tilt vision and the slipping wheels agree.
      EXPECT_LT(std::abs(result.wheels.lateral_residual_m), slam_config.wheels.vision_sigma_m) << "frame " << frame;
      EXPECT_LT(result.wheels.tilt_residual_deg, slam_config.wheels.vision_sigma_deg) << "frame " << frame;
    }
    return counts;
  };
  // The texture lasts 50 frames of 4 px.
  Counts counts = drive(good, 8);
  EXPECT_EQ(counts.slip_shaped, 0);
  EXPECT_EQ(counts.vision_trusted, 0);
  // The heading residual grows 0.6 deg a frame while the wheels keep the pose: slip-shaped from
  // the second frame (1.2 deg), a slip at the fourth. Then vision holds it while the wheels go on
  // turning 0.6 deg a frame, more than 0.8 / 3.
  counts = drive(slipping, 12);
  EXPECT_EQ(loop.wheel_slip_events(), 1);
  EXPECT_EQ(counts.vision_trusted, 12 - 3);
  counts = drive(good, 12);
  EXPECT_EQ(loop.wheel_slip_events(), 1);
  EXPECT_EQ(counts.vision_trusted, 0) << "the slip outlasts the wheels' error";
  drive(slipping, 12);
  EXPECT_EQ(loop.wheel_slip_events(), 2);
  // Vision kept the pose on the wall's true path: of the wheels' yaw only the frames before each
  // slip was confirmed remain (the next registrations against the reference take it back out).
  EXPECT_NEAR(result.T_world_cam.translation().x(), WallSequence::metres(4 * (frame - 1)), 0.01);
  EXPECT_LT(Eigen::AngleAxisd(result.T_world_cam.rotation()).angle(), 0.01);
}

// Where vision cannot be checked for planarity (here the wheels' prior tilts, so vision and
// wheels differ in tilt from the first frame on), a heading residual that keeps turning one way
// still declares the slip, after wheel_slip_heading_frames frames instead of wheel_slip_min_frames.
TEST_P(SlamLoopWheels, AHeadingResidualTurningOneWayIsASlipWhateverTheTilt) {
  SlamConfig slam_config = synthetic_vision_config();
  SlamLoop loop(slam_config, pinhole_on_base());
  const nav::MotionPrior good = sideways_prior(speed_m_);
  nav::MotionPrior slipping_and_tilting = sideways_prior(speed_m_, 0.6 * M_PI / 180.0);
  Eigen::Isometry3d roll = Eigen::Isometry3d::Identity();
  roll.linear() = Eigen::AngleAxisd(0.5 * M_PI / 180.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Isometry3d T_base_cam = camera_on_base();
  slipping_and_tilting.T_previous_current = T_base_cam.inverse() * roll * T_base_cam * slipping_and_tilting.T_previous_current;
  FrameResult result;
  int frame = 0;
  for (; frame < 8; ++frame) result = loop.process(wall_.frame(4 * frame, static_cast<std::uint32_t>(frame)), &good);
  ASSERT_EQ(result.status, FrameStatus::kTracking);
  int event_at = 0;
  for (int k = 1; k <= 12 && event_at == 0; ++k, ++frame) {
    result = loop.process(wall_.frame(4 * frame, static_cast<std::uint32_t>(frame)), &slipping_and_tilting);
    ASSERT_TRUE(result.wheels.compared) << "frame " << frame << ": " << result.failure_reason;
    EXPECT_FALSE(result.wheels.slip_shaped) << "frame " << frame << ": tilt " << result.wheels.tilt_residual_deg;
    if (result.wheels.slip_event) event_at = k;
  }
  // The heading residual grows 0.6 deg a frame: 0.8 deg or more from the second frame, the
  // eighth such frame is the ninth.
  EXPECT_EQ(event_at, 1 + slam_config.wheels.slip_heading_frames);
  EXPECT_EQ(loop.wheel_slip_events(), 1);
  EXPECT_TRUE(result.wheels.vision_trusted);
  EXPECT_LT(std::abs(result.wheels.lateral_residual_m), 2.0 * slam_config.wheels.vision_sigma_m);
}

// Strong vision that disagrees with the wheels as the base cannot move (across its drive
// direction) is a registration error for as long as it lasts; a disagreement the base can make
// (along it, a robot pushed with its wheels locked) goes to vision after wheel_override_min_frames.
TEST_P(SlamLoopWheels, StrongVisionWinsOnlyADisagreementTheBaseCanMake) {
  SlamConfig slam_config = synthetic_vision_config();
  slam_config.wheels.strong_inliers = slam_config.min_inliers;  // every accepted registration is strong
  slam_config.wheels.override_min_frames = 3;
  // The wall sequence moves the camera along its x axis. Looking forward, that is across the
  // base's drive direction; looking to the left side (camera x = base x, y = −base z, z = base y),
  // along it.
  Eigen::Isometry3d looking_left = Eigen::Isometry3d::Identity();
  looking_left.linear() << 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0;
  looking_left.translation() = Eigen::Vector3d(0.0, 0.1, 0.5);
  struct Case {
    const char* name;
    Eigen::Isometry3d T_base_cam;
    double base_x_per_camera_x;
    double base_y_per_camera_x;
    bool base_can_make_it;
  };
  for (const Case& c : {Case{"across", camera_on_base(), 0.0, -1.0, false}, Case{"along", looking_left, 1.0, 0.0, true}}) {
    SCOPED_TRACE(c.name);
    hal::Calibration calibration = pinhole();
    calibration.rgb.T_base_cam = c.T_base_cam;
    SlamLoop loop(slam_config, calibration);
    const auto prior_for = [&](double camera_x_m) {
      return nav::camera_motion_prior(c.base_x_per_camera_x * camera_x_m, c.base_y_per_camera_x * camera_x_m, 0.0,
                                 frame_covariance(), c.T_base_cam);
    };
    const nav::MotionPrior good = prior_for(speed_m_);
    // 3 cm a frame the camera did not move (6 sigma).
    const nav::MotionPrior wrong = prior_for(speed_m_ + 0.03);
    int frame = 0;
    FrameResult result;
    for (; frame < 5; ++frame) result = loop.process(wall_.frame(4 * frame, static_cast<std::uint32_t>(frame)), &good);
    ASSERT_EQ(result.status, FrameStatus::kTracking);
    // Three frames: while the wheels keep the pose their error adds up to 9 cm, inside the loop's
    // 10 cm deviation gate.
    for (int k = 1; k <= 3; ++k, ++frame) {
      result = loop.process(wall_.frame(4 * frame, static_cast<std::uint32_t>(frame)), &wrong);
      ASSERT_TRUE(result.wheels.compared) << "frame " << frame << ": " << result.failure_reason;
      EXPECT_TRUE(result.wheels.disagree) << "frame " << frame;
      EXPECT_FALSE(result.wheels.slip_shaped) << "frame " << frame;
      const bool vision_wins = c.base_can_make_it && k >= slam_config.wheels.override_min_frames;
      EXPECT_EQ(result.wheels.vision_trusted, vision_wins)
          << "frame " << frame << ": residual forward " << result.wheels.forward_residual_m << " m, across "
          << result.wheels.lateral_residual_m << " m, height " << result.wheels.height_residual_m << " m, yaw "
          << result.wheels.yaw_residual_deg << " deg, tilt " << result.wheels.tilt_residual_deg << " deg";
      EXPECT_EQ(result.status, vision_wins ? FrameStatus::kTracking : FrameStatus::kWheels) << "frame " << frame;
    }
    EXPECT_EQ(loop.wheel_slip_events(), c.base_can_make_it ? 1 : 0);
    // Vision holds the pose while the disagreement lasts; the wheels' error stays out of it.
    for (int k = 0; k < 3 && c.base_can_make_it; ++k, ++frame) {
      result = loop.process(wall_.frame(4 * frame, static_cast<std::uint32_t>(frame)), &wrong);
      EXPECT_TRUE(result.wheels.vision_trusted) << "frame " << frame;
    }
    if (c.base_can_make_it) {
      EXPECT_NEAR(result.T_world_cam.translation().x(), WallSequence::metres(4 * (frame - 1)), 0.01);
    }
  }
}

TEST_P(SlamLoopWheels, WeakVisionThatDisagreesGivesWayToTheWheels) {
  SlamConfig slam_config = config();
  slam_config.wheels.strong_inliers = 10000;  // no registration is strong enough to overrule them
  // A disagreement the frame's own test sees, yet within the loop's deviation gate (10 cm).
  slam_config.wheels.vision_sigma_m = 0.01;
  SlamLoop loop(slam_config, pinhole_on_base());
  const nav::MotionPrior good = sideways_prior(speed_m_);
  FrameResult result;
  for (int i = 0; i < 5; ++i) result = loop.process(wall_.frame(4 * i, static_cast<std::uint32_t>(i)), &good);
  ASSERT_EQ(result.status, FrameStatus::kTracking);
  const Eigen::Isometry3d T_world_previous = result.T_world_cam;
  // The wheels say 8 cm more than the view shows (8 sigma of the vision noise).
  const nav::MotionPrior far = sideways_prior(speed_m_ + 0.08);
  result = loop.process(wall_.frame(20, 5), &far);
  EXPECT_EQ(result.status, FrameStatus::kWheels) << result.failure_reason;
  EXPECT_TRUE(result.wheels.compared);
  EXPECT_TRUE(result.wheels.disagree);
  EXPECT_TRUE(result.wheels.wheels_trusted);
  EXPECT_GT(result.wheels.frame_distance_sq, slam_config.wheels.gate_chi2);
  EXPECT_EQ(result.failure_reason, "registration disagrees with the wheels");
  const Eigen::Isometry3d expected = T_world_previous * far.T_previous_current;
  EXPECT_LT((result.T_world_cam.translation() - expected.translation()).norm(), 1e-6);
  EXPECT_EQ(loop.wheel_slip_events(), 0);
}

INSTANTIATE_TEST_SUITE_P(Modes, SlamLoopWheels, ::testing::Values(Mode::kBaseline, Mode::kPhotometric),
                         [](const auto& param_info) { return std::string(to_string(param_info.param)); });

TEST(SlamLoopWheelsGeometric, FramesWithoutGeometryFollowTheWheels) {
  SlamConfig config;
  config.mode = Mode::kGeometric;
  SlamLoop loop(config, pinhole_on_base());
  WallSequence wall;
  const nav::MotionPrior prior = sideways_prior(WallSequence::metres(4));
  FrameResult result = loop.process(wall.frame(0, 0), &prior);
  ASSERT_EQ(result.status, FrameStatus::kFirstFrame);
  // A flat wall gives the depth-only front-end nothing to register: every frame is the wheels'.
  for (int i = 1; i < 20; ++i) {
    result = loop.process(wall.frame(4 * i, static_cast<std::uint32_t>(i)), &prior);
    ASSERT_EQ(result.status, FrameStatus::kWheels) << "frame " << i;
  }
  EXPECT_NEAR(result.T_world_cam.translation().x(), 19 * WallSequence::metres(4), 1e-6);
  // Without the prior the same frames fail.
  result = loop.process(wall.frame(80, 20));
  EXPECT_EQ(result.status, FrameStatus::kFailed);
}

}  // namespace
}  // namespace rankslam::slam
