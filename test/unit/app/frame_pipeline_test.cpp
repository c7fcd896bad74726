#include "frame_pipeline.hpp"

#include "rankslam/nav/wheel_frame.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace rankslam::app {
namespace {

/// Wheel frames at 100 Hz of a base turning gently, with another identifier in between.
std::vector<hal::CanFrame> recorded_can_log(const hal::WheelGeometry& geometry) {
  std::vector<hal::CanFrame> frames;
  for (int i = 0; i < 200; ++i) {
    const std::int64_t stamp_ns = 1'700'000'000'000'000'000 + i * 10'000'000LL;
    nav::WheelTicks ticks;
    ticks.left_ticks = static_cast<std::uint32_t>(30 * i);
    ticks.right_ticks = static_cast<std::uint32_t>(34 * i);
    ticks.rolling_counter = static_cast<std::uint8_t>(i);
    frames.push_back(nav::encode_wheel_ticks(ticks, geometry.can_id, stamp_ns));
    hal::CanFrame other;
    other.stamp_ns = stamp_ns + 5'000'000;
    other.id = 0x300;
    other.length = 2;
    frames.push_back(other);
  }
  return frames;
}

// The replay bus must give every camera frame the prior replay gave it when it fed the
// odometry straight from the recording: the frames up to the stamp and the first wheel frame
// after it.
TEST(ReplayedWheels, GiveThePriorsOfFeedingTheRecordingDirectly) {
  const hal::WheelGeometry geometry;
  const std::vector<hal::CanFrame> frames = recorded_can_log(geometry);
  const Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  nav::WheelPrior direct({}, geometry, T_base_cam);
  nav::WheelPrior through_bus({}, geometry, T_base_cam);
  replay::ReplayCanBus bus(frames, {geometry.can_id});
  ASSERT_EQ(bus.open(), "");
  ReplayedWheels replayed(bus, through_bus);

  std::size_t next = 0;
  int compared = 0;
  for (int k = 0; k < 60; ++k) {
    // Camera frames at 30 Hz, stamps as a recording's (microseconds, seconds as double).
    const double stamp_s = 1'700'000'000.0 + 0.0123 + k / 30.0;
    const std::int64_t stamp_ns = nav::recording_stamp_ns(stamp_s);
    while (next < frames.size()) {
      const hal::CanFrame& frame = frames[next++];
      const nav::WheelFrameResult fed = direct.update(frame);
      if (frame.stamp_ns >= stamp_ns && fed != nav::WheelFrameResult::kNotWheelFrame) break;
    }
    const nav::MotionPrior* expected = direct.prior_for(stamp_ns);
    nav::MotionPrior got;
    const bool have = replayed.prior_for(stamp_ns, got);
    ASSERT_EQ(have, expected != nullptr) << "frame " << k;
    if (!have) continue;
    EXPECT_TRUE(got.T_previous_current.matrix() == expected->T_previous_current.matrix()) << "frame " << k;
    EXPECT_TRUE(got.covariance == expected->covariance) << "frame " << k;
    ++compared;
  }
  EXPECT_GT(compared, 50);
  EXPECT_EQ(through_bus.odometry().newest_stamp_ns(), direct.odometry().newest_stamp_ns());
}

}  // namespace
}  // namespace rankslam::app
