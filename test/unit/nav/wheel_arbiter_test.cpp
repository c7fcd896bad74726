// The wheel/vision arbiter on its own: the camera motion prior, agreement (the covariance-weighted
// combination), a registration error overruled by the wheels, a slipping wheel and a base moved
// without its wheels overruled by vision, and the runs starting afresh after a frame without a
// comparison.
#include "rankslam/nav/wheel_arbiter.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/units.hpp"
#include "allocation_counter.hpp"

#include <gtest/gtest.h>

namespace rankslam::nav {
namespace {

// The camera 0.2 m ahead of the base origin, 0.5 m up, looking forward along the base's x axis:
// camera x = −base y, camera y = −base z, camera z = base x.
Eigen::Isometry3d camera_on_base() {
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  T_base_cam.linear() << 0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0;
  T_base_cam.translation() = Eigen::Vector3d(0.2, 0.0, 0.5);
  return T_base_cam;
}

// Wheel noise over one frame: 1 mm in x and y, 0.26 deg in yaw.
Eigen::Matrix3d frame_covariance() { return Eigen::Vector3d(1e-6, 1e-6, 2e-5).asDiagonal(); }

// The base driving 2 cm forward per frame.
MotionPrior forward_prior() { return camera_motion_prior(0.02, 0.0, 0.0, frame_covariance(), camera_on_base()); }

// The camera motion of a base motion (x, y, yaw) and an extra camera-frame error.
Eigen::Isometry3d base_step(double x_m, double y_m, double yaw_rad) {
  Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
  D.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  D.translation() = Eigen::Vector3d(x_m, y_m, 0.0);
  return camera_on_base().inverse() * D * camera_on_base();
}

TEST(CameraMotionPrior, IsTheBaseMotionSeenFromTheCameraWithItsCovariancePropagated) {
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  T_base_cam.linear() = (Eigen::AngleAxisd(-1.4, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(-1.7, Eigen::Vector3d::UnitX()))
                            .toRotationMatrix();
  T_base_cam.translation() = Eigen::Vector3d(0.15, -0.05, 0.45);
  const double x = 0.02;
  const double y = 0.004;
  const double yaw = 0.03;
  Eigen::Matrix3d covariance;
  covariance << 4e-6, 1e-6, 2e-6, 1e-6, 3e-6, -1e-6, 2e-6, -1e-6, 9e-6;
  const MotionPrior prior = camera_motion_prior(x, y, yaw, covariance, T_base_cam);

  const auto base_motion = [](double bx, double by, double byaw) {
    Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
    D.linear() = Eigen::AngleAxisd(byaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    D.translation() = Eigen::Vector3d(bx, by, 0.0);
    return D;
  };
  const Eigen::Isometry3d expected = T_base_cam.inverse() * base_motion(x, y, yaw) * T_base_cam;
  EXPECT_LT((prior.T_previous_current.matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-12);

  // Jacobian of ξ (camera motion = exp(ξ)·mean) with respect to (x, y, yaw), by central
  // differences, against the propagated covariance.
  Eigen::Matrix<double, 6, 3> jacobian;
  const double h = 1e-6;
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector3d plus(x, y, yaw);
    Eigen::Vector3d minus(x, y, yaw);
    plus[i] += h;
    minus[i] -= h;
    const Eigen::Isometry3d C_plus = T_base_cam.inverse() * base_motion(plus[0], plus[1], plus[2]) * T_base_cam;
    const Eigen::Isometry3d C_minus = T_base_cam.inverse() * base_motion(minus[0], minus[1], minus[2]) * T_base_cam;
    jacobian.col(i) = (lie::log_so3_r3(C_plus * expected.inverse()) - lie::log_so3_r3(C_minus * expected.inverse())) / (2 * h);
  }
  const Eigen::Matrix<double, 6, 6> numeric = jacobian * covariance * jacobian.transpose();
  EXPECT_LT((prior.covariance - numeric).cwiseAbs().maxCoeff(), 1e-10) << prior.covariance << "\n\n" << numeric;
  // A planar motion leaves the camera's motion certain across the floor's normal.
  const Eigen::Vector3d floor_normal_cam = T_base_cam.rotation().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(floor_normal_cam.dot(prior.covariance.bottomRightCorner<3, 3>() * floor_normal_cam), 0.0, 1e-15);
}

class WheelArbiterTest : public ::testing::Test {
 protected:
  // One frame: the registration measured `registered` (the camera's motion since the previous
  // frame, at the identity); returns whether it kept the pose, with the pose and the check.
  bool frame(const Eigen::Isometry3d& registered, int inliers = 100) {
    check_ = WheelCheck{};
    T_world_cam_ = registered;
    return arbiter_.arbitrate(forward_prior(), Eigen::Isometry3d::Identity(), inliers, T_world_cam_, check_);
  }

  WheelArbiterConfig config_;
  WheelArbiter arbiter_{config_, camera_on_base()};
  WheelCheck check_;
  Eigen::Isometry3d T_world_cam_ = Eigen::Isometry3d::Identity();
};

TEST_F(WheelArbiterTest, AgreementCombinesBothByTheirCovariances) {
  // 1 cm more than the wheels along the drive direction: within the gate.
  ASSERT_TRUE(frame(base_step(0.03, 0.0, 0.0)));
  EXPECT_TRUE(check_.compared);
  EXPECT_TRUE(check_.fused);
  EXPECT_FALSE(check_.disagree);
  EXPECT_NEAR(check_.forward_residual_m, 0.01, 1e-9);
  EXPECT_NEAR(check_.lateral_residual_m, 0.0, 1e-9);
  // The combination lies between the wheels (2 cm) and vision (3 cm), nearer the wheels, whose
  // 1 mm beats vision's 2 cm; across the floor it keeps the wheels' zero.
  const Eigen::Isometry3d in_base = camera_on_base() * T_world_cam_ * camera_on_base().inverse();
  EXPECT_GT(in_base.translation().x(), 0.02);
  EXPECT_LT(in_base.translation().x(), 0.0205);
  EXPECT_NEAR(in_base.translation().z(), 0.0, 1e-12);
  EXPECT_EQ(arbiter_.slip_events(), 0);
}

TEST_F(WheelArbiterTest, ASingleDisagreementIsTheRegistrationsError) {
  // 10 cm sideways (across the drive direction): no base makes that.
  EXPECT_FALSE(frame(base_step(0.02, 0.10, 0.0)));
  EXPECT_TRUE(check_.disagree);
  EXPECT_TRUE(check_.wheels_trusted);
  EXPECT_FALSE(check_.vision_trusted);
  EXPECT_NEAR(check_.lateral_residual_m, 0.10, 1e-9);
  EXPECT_EQ(arbiter_.slip_events(), 0);
}

TEST_F(WheelArbiterTest, ASlipShapedRunHandsThePoseToVision) {
  // Heading residuals growing by 0.5 deg per frame, nothing across: one wheel slipping.
  const double step_deg = 0.5;
  int event_at = -1;
  for (int k = 1; k <= 6 && event_at < 0; ++k) {
    const bool kept = frame(base_step(0.02, 0.0, deg_to_rad(step_deg * k)));
    if (check_.slip_event) {
      event_at = k;
      EXPECT_TRUE(kept);
      EXPECT_TRUE(check_.vision_trusted);
    }
  }
  // 0.8 deg is reached at the second frame; three slip-shaped frames in a row make the event.
  EXPECT_EQ(event_at, 4);
  EXPECT_EQ(arbiter_.slip_events(), 1);
  // Vision holds while the heading keeps turning the slip's way at the least slip rate.
  EXPECT_TRUE(frame(base_step(0.02, 0.0, deg_to_rad(arbiter_.least_slip_turn_deg() + 0.01))));
  EXPECT_TRUE(check_.vision_trusted);
  EXPECT_FALSE(check_.slip_event);
  EXPECT_EQ(arbiter_.slip_events(), 1);
}

TEST_F(WheelArbiterTest, StrongVisionMovedWithoutTheWheelsOverrulesThemAfterARun) {
  // 12 cm more along the drive direction on every frame (6 vision sigmas), a strong registration:
  // a pushed robot.
  const Eigen::Isometry3d pushed = base_step(0.14, 0.0, 0.0);
  for (int k = 1; k < config_.override_min_frames; ++k) {
    EXPECT_FALSE(frame(pushed)) << "frame " << k;
    EXPECT_EQ(check_.disagree_in_a_row, k);
  }
  EXPECT_TRUE(frame(pushed));
  EXPECT_TRUE(check_.slip_event);
  EXPECT_EQ(arbiter_.slip_events(), 1);
}

TEST_F(WheelArbiterTest, WeakVisionNeverOverrulesTheWheels) {
  const Eigen::Isometry3d pushed = base_step(0.14, 0.0, 0.0);
  for (int k = 0; k < 3 * config_.override_min_frames; ++k) {
    EXPECT_FALSE(frame(pushed, config_.strong_inliers - 1));
  }
  EXPECT_EQ(arbiter_.slip_events(), 0);
}

TEST_F(WheelArbiterTest, AFrameWithoutAComparisonStartsTheRunsAfresh) {
  const Eigen::Isometry3d pushed = base_step(0.14, 0.0, 0.0);
  for (int k = 1; k < config_.override_min_frames; ++k) EXPECT_FALSE(frame(pushed));
  arbiter_.interrupt();
  EXPECT_FALSE(frame(pushed));
  EXPECT_EQ(check_.disagree_in_a_row, 1);
  EXPECT_EQ(arbiter_.slip_events(), 0);
}

TEST_F(WheelArbiterTest, ArbitratesWithoutAllocating) {
  (void)frame(base_step(0.03, 0.0, 0.0));
  const test_support::CountAllocations count;
  for (int k = 0; k < 100; ++k) (void)frame(base_step(0.02 + 0.001 * (k % 7), 0.0, 0.0));
  EXPECT_EQ(count.allocations(), 0);
}

}  // namespace
}  // namespace rankslam::nav
