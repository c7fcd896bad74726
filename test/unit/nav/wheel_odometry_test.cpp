// Differential-drive odometry: every frame defect the CAN stream can carry, the arc model
// against closed-form geometry, the covariance against its closed-form growth, and the
// interpolated relative motion.
#include "rankslam/nav/wheel_odometry.hpp"

#include "allocation_counter.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <numbers>

namespace rankslam::nav {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr std::int64_t kFrameNs = 10'000'000;  // 100 Hz

// Wheels whose tick is exactly one millimetre (circumference 1 m, 1000 ticks), so whole-tick
// travels make the arc model's result exact and comparable with closed-form geometry.
hal::WheelGeometry millimetre_wheels() {
  hal::WheelGeometry wheels;
  wheels.radius_m = 1.0 / (2.0 * kPi);
  wheels.ticks_per_revolution = 1000;
  wheels.track_width_m = 0.4;
  return wheels;
}

// The base controller: true wheel travel in, WheelTicks frames out (24-bit counters from
// chosen offsets, rolling counter, 100 Hz stamps).
class WheelSource {
 public:
  WheelSource(const hal::WheelGeometry& wheels, std::uint32_t left_offset, std::uint32_t right_offset,
              std::int64_t start_ns = 1'000'000'000)
      : ticks_per_m_(wheels.ticks_per_revolution / (2.0 * kPi * wheels.radius_m)),
        left_offset_(left_offset),
        right_offset_(right_offset),
        stamp_ns_(start_ns) {}

  [[nodiscard]] WheelTicks ticks() const {
    WheelTicks t;
    t.left_ticks = wrap(left_offset_, left_m_);
    t.right_ticks = wrap(right_offset_, right_m_);
    t.rolling_counter = counter_;
    return t;
  }
  [[nodiscard]] std::int64_t stamp_ns() const { return stamp_ns_; }

  /// Both wheels roll on by the given distances over dt_ns; the next frame.
  WheelTicks advance(double left_m, double right_m, std::int64_t dt_ns = kFrameNs) {
    left_m_ += left_m;
    right_m_ += right_m;
    stamp_ns_ += dt_ns;
    ++counter_;
    return ticks();
  }

 private:
  [[nodiscard]] std::uint32_t wrap(std::uint32_t offset, double travel_m) const {
    const auto m = static_cast<std::int64_t>(kWheelTickModulus);
    const std::int64_t value = (static_cast<std::int64_t>(offset) + std::llround(travel_m * ticks_per_m_)) % m;
    return static_cast<std::uint32_t>(value < 0 ? value + m : value);
  }

  double ticks_per_m_;
  std::uint32_t left_offset_;
  std::uint32_t right_offset_;
  double left_m_ = 0.0;
  double right_m_ = 0.0;
  std::int64_t stamp_ns_;
  std::uint8_t counter_ = 0;
};

// Feeds the source's current frame, expecting `expected`.
void feed(WheelOdometry& odometry, const WheelSource& source, WheelFrameResult expected) {
  const WheelFrameResult result = odometry.update(source.ticks(), source.stamp_ns());
  ASSERT_EQ(result, expected) << to_string(result) << " instead of " << to_string(expected);
}

WheelOdometryConfig config_with(double wheel_variance_per_m = 1e-4) {
  WheelOdometryConfig config;
  config.wheel_variance_per_m = wheel_variance_per_m;
  return config;
}

TEST(WheelOdometry, ValidateNamesTheField) {
  EXPECT_TRUE(validate(WheelOdometryConfig{}, hal::WheelGeometry{}).empty());
  WheelOdometryConfig config;
  config.max_frame_gap_s = 5.0;
  EXPECT_NE(validate(config, hal::WheelGeometry{}).find("max_frame_gap_s"), std::string::npos);
  hal::WheelGeometry wheels;
  wheels.track_width_m = 0.0;
  EXPECT_NE(validate(WheelOdometryConfig{}, wheels).find("wheels.track_width_m"), std::string::npos);
  wheels = {};
  wheels.ticks_per_revolution = -1;
  EXPECT_NE(validate(WheelOdometryConfig{}, wheels).find("ticks_per_revolution"), std::string::npos);
}

TEST(WheelOdometry, StraightLine) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 1000, 5000);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 100; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  const WheelOdometryState& state = odometry.state();
  EXPECT_NEAR(state.T_odom_base.x_m, 1.0, 1e-12);
  EXPECT_NEAR(state.T_odom_base.y_m, 0.0, 1e-12);
  EXPECT_NEAR(state.T_odom_base.yaw_rad, 0.0, 1e-12);
  EXPECT_NEAR(state.linear_velocity_mps, 1.0, 1e-9);  // 10 mm per 10 ms
  EXPECT_NEAR(state.angular_velocity_rps, 0.0, 1e-12);
  EXPECT_NEAR(state.distance_m, 1.0, 1e-12);
  EXPECT_EQ(odometry.stats().frames_integrated, 100U);
  EXPECT_EQ(state.stamp_ns, source.stamp_ns());
}

TEST(WheelOdometry, PureRotationStaysInPlace) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  // ±10 mm per frame on a 0.4 m track: 0.05 rad per frame, 40 frames = 2 rad.
  for (int i = 0; i < 40; ++i) {
    source.advance(-0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  const WheelOdometryState& state = odometry.state();
  EXPECT_NEAR(state.T_odom_base.x_m, 0.0, 1e-12);
  EXPECT_NEAR(state.T_odom_base.y_m, 0.0, 1e-12);
  EXPECT_NEAR(state.T_odom_base.yaw_rad, 2.0, 1e-12);
  EXPECT_NEAR(state.angular_velocity_rps, 5.0, 1e-9);
  EXPECT_NEAR(state.linear_velocity_mps, 0.0, 1e-12);
  EXPECT_NEAR(state.turned_rad, 2.0, 1e-12);
  // Another 5 rad: the yaw wraps into [-π, π).
  for (int i = 0; i < 100; ++i) {
    source.advance(-0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  EXPECT_NEAR(odometry.state().T_odom_base.yaw_rad, 7.0 - 2.0 * kPi, 1e-9);
}

TEST(WheelOdometry, ArcModelIsExactOnAConstantCurvaturePath) {
  // 80 mm left, 120 mm right per frame on a 0.4 m track: Δs = 0.1 m, Δθ = 0.1 rad, radius 1 m.
  // The chord model lands on the circle exactly; a midpoint (Euler at θ + Δθ/2) model would be
  // off by Δs·Δθ²/24 ≈ 4e-5 m per step.
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 7, 9);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 1; i <= 20; ++i) {
    source.advance(0.080, 0.120, 100'000'000);  // 10 Hz keeps the wheels below max speed
    feed(odometry, source, WheelFrameResult::kIntegrated);
    const double theta = 0.1 * i;
    EXPECT_NEAR(odometry.state().T_odom_base.x_m, std::sin(theta), 1e-12) << "step " << i;
    EXPECT_NEAR(odometry.state().T_odom_base.y_m, 1.0 - std::cos(theta), 1e-12) << "step " << i;
    EXPECT_NEAR(odometry.state().T_odom_base.yaw_rad, theta, 1e-12) << "step " << i;
  }
}

TEST(WheelOdometry, CircleOfKnownRadiusReturnsToStart) {
  // The robot's real geometry (4096 ticks, 5 cm wheels, 0.3 m track), a circle of radius 1 m at
  // 0.3 m/s sampled at 100 Hz, counters quantised to whole ticks. The counters are absolute,
  // so quantisation does not accumulate: yaw is off by at most 2 ticks over the track
  // (2·7.7e-5 / 0.3 = 5.1e-4 rad) and the position by about radius × that.
  const hal::WheelGeometry wheels{};
  const double metres_per_tick = 2.0 * kPi * wheels.radius_m / wheels.ticks_per_revolution;
  const double yaw_tolerance = 2.0 * metres_per_tick / wheels.track_width_m;
  const double radius = 1.0;
  const double position_tolerance = radius * yaw_tolerance + 2.0 * metres_per_tick;
  WheelOdometry odometry(config_with(), wheels);
  // The left counter wraps forwards within the first metre.
  WheelSource source(wheels, kWheelTickModulus - 3000, 123456);
  feed(odometry, source, WheelFrameResult::kBaseline);
  const int frames = 2094;  // 2π m at 0.3 m/s
  const double dtheta = 2.0 * kPi / frames;
  for (int i = 1; i <= frames; ++i) {
    source.advance((radius - 0.5 * wheels.track_width_m) * dtheta, (radius + 0.5 * wheels.track_width_m) * dtheta);
    feed(odometry, source, WheelFrameResult::kIntegrated);
    if (i == frames / 2) {
      EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.0, position_tolerance);
      EXPECT_NEAR(odometry.state().T_odom_base.y_m, 2.0 * radius, position_tolerance);
      EXPECT_NEAR(std::abs(odometry.state().T_odom_base.yaw_rad), kPi, yaw_tolerance);
    }
  }
  const WheelOdometryState& state = odometry.state();
  EXPECT_NEAR(state.T_odom_base.x_m, 0.0, position_tolerance);
  EXPECT_NEAR(state.T_odom_base.y_m, 0.0, position_tolerance);
  EXPECT_NEAR(state.T_odom_base.yaw_rad, 0.0, yaw_tolerance);
  EXPECT_NEAR(state.distance_m, 2.0 * kPi * radius, position_tolerance);
  // One frame's yaw change is off by at most two ticks over the track as well.
  EXPECT_NEAR(state.angular_velocity_rps, dtheta / 0.01, yaw_tolerance / 0.01);
}

TEST(WheelOdometry, CounterWrapsForward) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  // Both counters 50 ticks below the 24-bit wrap, 10 ticks per frame: they wrap at frame 5.
  WheelSource source(wheels, kWheelTickModulus - 50, kWheelTickModulus - 45);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 10; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  EXPECT_LT(source.ticks().left_ticks, 100U);  // wrapped
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.100, 1e-12);
  EXPECT_NEAR(odometry.state().T_odom_base.yaw_rad, 0.0, 1e-12);
  EXPECT_EQ(odometry.stats().implausible, 0U);
}

TEST(WheelOdometry, CounterWrapsBackward) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  // Reversing from counters just above zero: they wrap down to 2^24 - 1 and below.
  WheelSource source(wheels, 30, 25);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 10; ++i) {
    source.advance(-0.010, -0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  EXPECT_GT(source.ticks().left_ticks, kWheelTickModulus - 100);  // wrapped
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, -0.100, 1e-12);
  EXPECT_NEAR(odometry.state().T_odom_base.y_m, 0.0, 1e-12);
  EXPECT_NEAR(odometry.state().linear_velocity_mps, -1.0, 1e-9);
}

TEST(WheelOdometry, MissingFramesIntegrateTheTotalDelta) {
  // On a constant-curvature path the arc over the gap is the true path, so bridging five lost
  // frames lands exactly where the full stream does.
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry complete(config_with(), wheels);
  WheelOdometry gappy(config_with(), wheels);
  WheelSource source(wheels, 100, 200);
  feed(complete, source, WheelFrameResult::kBaseline);
  feed(gappy, source, WheelFrameResult::kBaseline);
  for (int i = 1; i <= 20; ++i) {
    source.advance(0.008, 0.012);
    feed(complete, source, WheelFrameResult::kIntegrated);
    if (i >= 5 && i <= 9) continue;  // lost on the bus
    feed(gappy, source, i == 10 ? WheelFrameResult::kIntegratedAcrossGap : WheelFrameResult::kIntegrated);
  }
  EXPECT_NEAR(gappy.state().T_odom_base.x_m, complete.state().T_odom_base.x_m, 1e-12);
  EXPECT_NEAR(gappy.state().T_odom_base.y_m, complete.state().T_odom_base.y_m, 1e-12);
  EXPECT_NEAR(gappy.state().T_odom_base.yaw_rad, complete.state().T_odom_base.yaw_rad, 1e-12);
  EXPECT_EQ(gappy.stats().gaps, 1U);
  EXPECT_EQ(gappy.stats().frames_missing, 5U);
  EXPECT_EQ(gappy.stats().frames_integrated, 15U);
  EXPECT_EQ(complete.stats().gaps, 0U);
  // The relative motion over the gap says frames were lost in it.
  RelativeMotion motion;
  ASSERT_EQ(gappy.relative_motion(gappy.oldest_stamp_ns(), gappy.newest_stamp_ns(), motion), RelativeMotionStatus::kOk);
  EXPECT_EQ(motion.missing_frames, 5);
}

TEST(WheelOdometry, DuplicatesAreIgnoredAndCounted) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  source.advance(0.010, 0.010);
  feed(odometry, source, WheelFrameResult::kIntegrated);
  // The same frame again, then the same rolling counter with a later receive stamp.
  feed(odometry, source, WheelFrameResult::kDuplicate);
  EXPECT_EQ(odometry.update(source.ticks(), source.stamp_ns() + 1'000'000), WheelFrameResult::kDuplicate);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.010, 1e-12);
  EXPECT_EQ(odometry.stats().duplicates, 2U);
  source.advance(0.010, 0.010);
  feed(odometry, source, WheelFrameResult::kIntegrated);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.020, 1e-12);
  EXPECT_EQ(odometry.stats().frames_received, 5U);
  EXPECT_EQ(odometry.stats().gaps, 0U);
}

TEST(WheelOdometry, OutOfOrderFramesAreDroppedAndCounted) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  source.advance(0.010, 0.010);
  const WheelTicks frame_1 = source.ticks();
  const std::int64_t stamp_1 = source.stamp_ns();
  source.advance(0.010, 0.010);
  // Frame 2 overtakes frame 1: frame 2 is integrated across a one-frame gap, frame 1 dropped.
  feed(odometry, source, WheelFrameResult::kIntegratedAcrossGap);
  EXPECT_EQ(odometry.update(frame_1, stamp_1), WheelFrameResult::kOutOfOrder);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.020, 1e-12);
  EXPECT_EQ(odometry.stats().out_of_order, 1U);
  for (int i = 0; i < 3; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.050, 1e-12);
  EXPECT_EQ(odometry.state().stamp_ns, source.stamp_ns());
}

TEST(WheelOdometry, BackwardTimestampJumpResetsTheBaselineWithoutPoseJump) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0, 50'000'000'000);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 10; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  // The receiver's clock steps back 20 s while the frames (rolling counter) carry on; the
  // wheels moved 30 mm meanwhile, which cannot be placed in time and is not integrated.
  source.advance(0.030, 0.030, -20'000'000'000);
  feed(odometry, source, WheelFrameResult::kTimestampJump);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.100, 1e-12);
  EXPECT_EQ(odometry.state().linear_velocity_mps, 0.0);
  EXPECT_EQ(odometry.stats().timestamp_jumps_backward, 1U);
  // The history restarted at the new clock.
  EXPECT_EQ(odometry.history_size(), 1U);
  EXPECT_EQ(odometry.oldest_stamp_ns(), source.stamp_ns());
  for (int i = 0; i < 5; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.150, 1e-12);
}

TEST(WheelOdometry, ForwardTimestampGapResetsTheBaselineWithoutPoseJump) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 10; ++i) {
    source.advance(0.010, 0.008);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  const Pose2d before = odometry.state().T_odom_base;
  const std::int64_t stamp_before = source.stamp_ns();
  // Nothing for 0.5 s (> max_frame_gap_s = 0.25 s), then the stream resumes.
  source.advance(0.150, 0.150, 500'000'000);
  feed(odometry, source, WheelFrameResult::kTimestampJump);
  EXPECT_EQ(odometry.state().T_odom_base.x_m, before.x_m);
  EXPECT_EQ(odometry.state().T_odom_base.y_m, before.y_m);
  EXPECT_EQ(odometry.state().T_odom_base.yaw_rad, before.yaw_rad);
  EXPECT_EQ(odometry.stats().timestamp_jumps_forward, 1U);
  source.advance(0.010, 0.010);
  feed(odometry, source, WheelFrameResult::kIntegrated);
  const double yaw = before.yaw_rad;
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, before.x_m + 0.010 * std::cos(yaw), 1e-12);
  EXPECT_NEAR(odometry.state().T_odom_base.y_m, before.y_m + 0.010 * std::sin(yaw), 1e-12);
  // The motion over the gap is unknown, on either side it is not.
  RelativeMotion motion;
  EXPECT_EQ(odometry.relative_motion(stamp_before - kFrameNs, source.stamp_ns(), motion),
            RelativeMotionStatus::kDiscontinuous);
  EXPECT_EQ(odometry.relative_motion(stamp_before - kFrameNs, stamp_before, motion), RelativeMotionStatus::kOk);
  EXPECT_EQ(odometry.relative_motion(source.stamp_ns() - kFrameNs, source.stamp_ns(), motion),
            RelativeMotionStatus::kOk);
  EXPECT_NEAR(motion.T_a_b.x_m, 0.010, 1e-12);
}

TEST(WheelOdometry, ImplausibleDeltaIsRejectedAndCounted) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 5; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  // A corrupted left counter: 5000 ticks (5 m) in 10 ms, far beyond max_wheel_speed_mps = 2.
  source.advance(0.010, 0.010);
  WheelTicks corrupted = source.ticks();
  corrupted.left_ticks = (corrupted.left_ticks + 5000) % kWheelTickModulus;
  EXPECT_EQ(odometry.update(corrupted, source.stamp_ns()), WheelFrameResult::kImplausible);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.050, 1e-12);
  EXPECT_EQ(odometry.stats().implausible, 1U);
  // The next good frame integrates from the last good one: no motion is lost.
  source.advance(0.010, 0.010);
  feed(odometry, source, WheelFrameResult::kIntegrated);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.070, 1e-12);
  EXPECT_NEAR(odometry.state().T_odom_base.yaw_rad, 0.0, 1e-12);
  // Just below the limit is motion: 2 m/s on both wheels over 10 ms is 20 mm.
  source.advance(0.020, 0.020);
  feed(odometry, source, WheelFrameResult::kIntegrated);
  EXPECT_EQ(odometry.stats().implausible, 1U);
  // Just above it (2.5 m/s, beyond the 2-tick allowance for read jitter) is not.
  source.advance(0.025, 0.025);
  feed(odometry, source, WheelFrameResult::kImplausible);
  EXPECT_EQ(odometry.stats().implausible, 2U);
}

TEST(WheelOdometry, RestartedCountersRebaseAfterTwoConsistentFrames) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 8'000'000, 9'000'000);
  feed(odometry, source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 5; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  // The controller restarts: counters from zero, still 10 mm per frame.
  WheelSource restarted(wheels, 0, 0, source.stamp_ns());
  restarted.advance(0.010, 0.010);
  feed(odometry, restarted, WheelFrameResult::kImplausible);
  restarted.advance(0.010, 0.010);
  feed(odometry, restarted, WheelFrameResult::kCountersRebased);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.050, 1e-12);  // no pose jump
  EXPECT_EQ(odometry.stats().counter_rebases, 1U);
  restarted.advance(0.010, 0.010);
  feed(odometry, restarted, WheelFrameResult::kIntegrated);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.060, 1e-12);
}

TEST(WheelOdometry, EncoderFaultDropsFramesAndRebaselines) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  source.advance(0.010, 0.010);
  feed(odometry, source, WheelFrameResult::kIntegrated);
  source.advance(0.010, 0.010);
  WheelTicks faulty = source.ticks();
  faulty.right_fault = true;
  EXPECT_EQ(odometry.update(faulty, source.stamp_ns()), WheelFrameResult::kEncoderFault);
  source.advance(0.010, 0.010);
  feed(odometry, source, WheelFrameResult::kBaseline);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.010, 1e-12);
  source.advance(0.010, 0.010);
  feed(odometry, source, WheelFrameResult::kIntegrated);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.020, 1e-12);
  EXPECT_EQ(odometry.stats().encoder_faults, 1U);
}

TEST(WheelOdometry, CanFramesAreFilteredByIdentifierAndLength) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(), wheels);
  WheelSource source(wheels, 0, 0);
  EXPECT_EQ(odometry.update(encode_wheel_ticks(source.ticks(), wheels.can_id, source.stamp_ns())),
            WheelFrameResult::kBaseline);
  source.advance(0.010, 0.010);
  EXPECT_EQ(odometry.update(encode_wheel_ticks(source.ticks(), 0x110, source.stamp_ns())),
            WheelFrameResult::kNotWheelFrame);
  hal::CanFrame short_frame = encode_wheel_ticks(source.ticks(), wheels.can_id, source.stamp_ns());
  short_frame.length = 6;
  EXPECT_EQ(odometry.update(short_frame), WheelFrameResult::kMalformed);
  EXPECT_EQ(odometry.update(encode_wheel_ticks(source.ticks(), wheels.can_id, source.stamp_ns())),
            WheelFrameResult::kIntegrated);
  EXPECT_NEAR(odometry.state().T_odom_base.x_m, 0.010, 1e-12);
  EXPECT_EQ(odometry.stats().frames_received, 3U);  // the other identifier is not ours
  EXPECT_EQ(odometry.stats().malformed, 1U);
}

TEST(WheelOdometry, CovarianceOfAStraightLineMatchesClosedForm) {
  // Per-wheel variance k|Δs|. Straight, N steps of Δs over length L on track b:
  //   var(x)   = Σ (k Δs_r + k Δs_l)/4            = k L / 2
  //   var(yaw) = Σ (k Δs_r + k Δs_l)/b²           = 2 k L / b²
  //   var(y)   = Σ_j var(Δθ_j) (L - (j - 1/2) Δs)² = (2k/b²)(L³/3 - L Δs²/12)
  // (a heading error made at a point swings everything after it; the chord leaves along the
  // mid-step heading, hence the half step).
  const double k = 1e-4;
  const hal::WheelGeometry wheels = millimetre_wheels();
  const double b = wheels.track_width_m;
  WheelOdometry odometry(config_with(k), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  double previous_trace = 0.0;
  const double step = 0.010;
  for (int i = 1; i <= 200; ++i) {
    source.advance(step, step);
    feed(odometry, source, WheelFrameResult::kIntegrated);
    const double trace = odometry.state().covariance.trace();
    ASSERT_GT(trace, previous_trace) << "covariance must grow with every metre, step " << i;
    previous_trace = trace;
  }
  const double L = 2.0;
  const Eigen::Matrix3d& P = odometry.state().covariance;
  EXPECT_NEAR(P(0, 0), k * L / 2.0, 1e-15);
  EXPECT_NEAR(P(2, 2), 2.0 * k * L / (b * b), 1e-15);
  EXPECT_NEAR(P(1, 1), 2.0 * k / (b * b) * (L * L * L / 3.0 - L * step * step / 12.0), 1e-14);
  // y and yaw correlate (a heading error moves the robot sideways), x stays independent.
  EXPECT_NEAR(P(1, 2), 2.0 * k / (b * b) * (L * L / 2.0), 1e-14);
  EXPECT_NEAR(P(0, 1), 0.0, 1e-15);
  EXPECT_NEAR(P(0, 2), 0.0, 1e-15);
  EXPECT_TRUE(P.isApprox(P.transpose()));
}

TEST(WheelOdometry, CovarianceGrowsWithTurning) {
  // Turning in place by α rolls each wheel b·α/2: var(yaw) = 2k(bα/2)/b² = kα/b, and the base
  // origin, though it stays in place on average, wanders by var(Δs) = k·bα/4 in total.
  const double k = 1e-4;
  const hal::WheelGeometry wheels = millimetre_wheels();
  const double b = wheels.track_width_m;
  WheelOdometry odometry(config_with(k), wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  const int frames = 60;  // 60 × 0.05 rad = 3 rad
  for (int i = 0; i < frames; ++i) {
    source.advance(-0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  const double alpha = 3.0;
  const double chord_factor_squared = std::pow(std::sin(0.025) / 0.025, 2);
  const Eigen::Matrix3d& P = odometry.state().covariance;
  EXPECT_NEAR(P(2, 2), k * alpha / b, 1e-15);
  EXPECT_NEAR(P(0, 0) + P(1, 1), chord_factor_squared * k * b * alpha / 4.0, 1e-15);
  EXPECT_GT(P(0, 0) + P(1, 1), 0.0);

  // The same 1 m driven straight, and driven with a 90° turn in place half-way: same distance,
  // but the turn adds heading uncertainty.
  WheelOdometry straight(config_with(k), wheels);
  WheelOdometry turning(config_with(k), wheels);
  WheelSource straight_source(wheels, 0, 0);
  WheelSource turning_source(wheels, 0, 0);
  feed(straight, straight_source, WheelFrameResult::kBaseline);
  feed(turning, turning_source, WheelFrameResult::kBaseline);
  for (int i = 0; i < 100; ++i) {
    straight_source.advance(0.010, 0.010);
    feed(straight, straight_source, WheelFrameResult::kIntegrated);
  }
  for (int i = 0; i < 50; ++i) {
    turning_source.advance(0.010, 0.010);
    feed(turning, turning_source, WheelFrameResult::kIntegrated);
  }
  // b·(π/2)/2 = 0.1π m per wheel ≈ 314 mm: 31 frames of 10 mm and one of 4 mm.
  for (int i = 0; i < 31; ++i) {
    turning_source.advance(-0.010, 0.010);
    feed(turning, turning_source, WheelFrameResult::kIntegrated);
  }
  turning_source.advance(-0.004, 0.004);
  feed(turning, turning_source, WheelFrameResult::kIntegrated);
  for (int i = 0; i < 50; ++i) {
    turning_source.advance(0.010, 0.010);
    feed(turning, turning_source, WheelFrameResult::kIntegrated);
  }
  const double turned = 0.314 * 2.0 / b;
  EXPECT_NEAR(turning.state().T_odom_base.yaw_rad, turned, 1e-12);
  EXPECT_NEAR(turning.state().distance_m, straight.state().distance_m, 1e-12);
  const Eigen::Matrix3d& P_straight = straight.state().covariance;
  const Eigen::Matrix3d& P_turning = turning.state().covariance;
  EXPECT_NEAR(P_turning(2, 2) - P_straight(2, 2), k * turned / b, 1e-15);
  EXPECT_GT(P_turning.trace(), P_straight.trace());
}

TEST(WheelOdometry, RelativeMotionInterpolatesBetweenFrames) {
  const double k = 1e-4;
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometry odometry(config_with(k), wheels);
  WheelSource source(wheels, 0, 0);
  const std::int64_t start = source.stamp_ns();
  feed(odometry, source, WheelFrameResult::kBaseline);
  // Turn 90° in place first (so odometry and base frames differ), then 10 mm per frame ahead.
  for (int i = 0; i < 31; ++i) {
    source.advance(-0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  const std::int64_t turned = source.stamp_ns();
  for (int i = 0; i < 10; ++i) {
    source.advance(0.010, 0.010);
    feed(odometry, source, WheelFrameResult::kIntegrated);
  }
  // 2.5 ms into the first straight frame to 7.5 ms into the fourth: 0.75 + 2 + 0.75 frames.
  RelativeMotion motion;
  ASSERT_EQ(odometry.relative_motion(turned + 2'500'000, turned + 37'500'000, motion), RelativeMotionStatus::kOk);
  EXPECT_NEAR(motion.T_a_b.x_m, 0.035, 1e-12);  // in the base frame at a: straight ahead
  EXPECT_NEAR(motion.T_a_b.y_m, 0.0, 1e-12);
  EXPECT_NEAR(motion.T_a_b.yaw_rad, 0.0, 1e-12);
  EXPECT_NEAR(motion.covariance(0, 0), k * 0.035 / 2.0, 1e-16);  // along the motion
  EXPECT_NEAR(motion.covariance(2, 2), 2.0 * k * 0.035 / (wheels.track_width_m * wheels.track_width_m), 1e-16);
  EXPECT_GT(motion.covariance(1, 1), 0.0);
  EXPECT_EQ(motion.missing_frames, 0);
  // Inside a single frame.
  ASSERT_EQ(odometry.relative_motion(turned + 2'500'000, turned + 5'000'000, motion), RelativeMotionStatus::kOk);
  EXPECT_NEAR(motion.T_a_b.x_m, 0.0025, 1e-12);
  // The pose at a stamp.
  Pose2d pose;
  ASSERT_TRUE(odometry.pose_at(turned + 5'000'000, pose));
  EXPECT_NEAR(pose.yaw_rad, 31 * 0.05, 1e-12);
  EXPECT_NEAR(pose.x_m, 0.005 * std::cos(31 * 0.05), 1e-12);
  EXPECT_NEAR(pose.y_m, 0.005 * std::sin(31 * 0.05), 1e-12);
  // Over the whole history from the start, where the pose was certain, the relative
  // covariance is the odometry's own.
  ASSERT_EQ(odometry.relative_motion(start, source.stamp_ns(), motion), RelativeMotionStatus::kOk);
  EXPECT_TRUE(motion.covariance.isApprox(odometry.state().covariance, 1e-12));
  EXPECT_NEAR(motion.T_a_b.x_m, odometry.state().T_odom_base.x_m, 1e-12);
  EXPECT_NEAR(motion.T_a_b.yaw_rad, odometry.state().T_odom_base.yaw_rad, 1e-12);
  // Out of the history, and the wrong way round.
  EXPECT_EQ(odometry.relative_motion(start - 1, source.stamp_ns(), motion), RelativeMotionStatus::kNotInHistory);
  EXPECT_EQ(odometry.relative_motion(start, source.stamp_ns() + 1, motion), RelativeMotionStatus::kNotInHistory);
  EXPECT_EQ(odometry.relative_motion(turned + 1, turned, motion), RelativeMotionStatus::kWrongOrder);
}

TEST(WheelOdometry, HistoryIsABoundedRingThatDoesNotAllocate) {
  const hal::WheelGeometry wheels = millimetre_wheels();
  WheelOdometryConfig config = config_with();
  config.history_capacity = 8;
  WheelOdometry odometry(config, wheels);
  WheelSource source(wheels, 0, 0);
  feed(odometry, source, WheelFrameResult::kBaseline);
  long allocations = -1;
  {
    const test_support::CountAllocations count;
    for (int i = 0; i < 500; ++i) {
      source.advance(0.004, 0.006);
      odometry.update(encode_wheel_ticks(source.ticks(), wheels.can_id, source.stamp_ns()));
      RelativeMotion motion;
      static_cast<void>(odometry.relative_motion(odometry.oldest_stamp_ns() + 1, odometry.newest_stamp_ns(), motion));
    }
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(odometry.stats().frames_integrated, 500U);
  EXPECT_EQ(odometry.history_size(), 8U);
  EXPECT_EQ(odometry.oldest_stamp_ns(), source.stamp_ns() - 7 * kFrameNs);
  EXPECT_EQ(odometry.newest_stamp_ns(), source.stamp_ns());
  // The newest seven steps are still there to interpolate over.
  RelativeMotion motion;
  ASSERT_EQ(odometry.relative_motion(odometry.oldest_stamp_ns(), odometry.newest_stamp_ns(), motion),
            RelativeMotionStatus::kOk);
  EXPECT_NEAR(motion.T_a_b.yaw_rad, 7 * 0.002 / wheels.track_width_m, 1e-12);
}

}  // namespace
}  // namespace rankslam::nav
