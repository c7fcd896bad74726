#include "rankslam/nav/pose_output.hpp"

#include "rankslam/nav/wheel_frame.hpp"

#include <gtest/gtest.h>

#include <deque>
#include <numbers>
#include <vector>

namespace rankslam::nav {
namespace {

constexpr std::uint32_t kWheelId = 0x101;

/// Hands out queued frames, keeps what is sent.
class QueueBus final : public hal::CanBus {
 public:
  std::string open() override { return {}; }
  hal::ReadStatus receive(hal::CanFrame& frame, std::chrono::milliseconds) override {
    if (inbox.empty()) return hal::ReadStatus::kTimeout;
    frame = inbox.front();
    inbox.pop_front();
    return hal::ReadStatus::kOk;
  }
  hal::ReadStatus send(const hal::CanFrame& frame) override {
    sent.push_back(frame);
    return hal::ReadStatus::kOk;
  }
  void close() override {}
  std::deque<hal::CanFrame> inbox;
  std::vector<hal::CanFrame> sent;
};

class ManualClock final : public hal::Clock {
 public:
  std::int64_t now_ns() const override { return now; }
  std::int64_t now = 1'000'000'000;
};

hal::CanFrame wheel_frame(std::uint32_t ticks, std::uint8_t counter, std::int64_t stamp_ns) {
  WheelTicks t;
  t.left_ticks = ticks;
  t.right_ticks = ticks;
  t.rolling_counter = counter;
  return encode_wheel_ticks(t, kWheelId, stamp_ns);
}

struct Fixture {
  QueueBus bus;
  ManualClock clock;
  PoseMailbox mailbox;
  LiveWheels wheels;
  PoseOutputOptions options;
  void drain(PoseOutput& output) {
    while (!bus.inbox.empty()) output.step();
  }
};

TEST(PoseOutput, DecodesWheelFramesCountingGapsAndMalformedOnes) {
  Fixture f;
  f.wheels.enable({}, hal::WheelGeometry{}, Eigen::Isometry3d::Identity(), nullptr);
  PoseOutput output(f.options, f.bus, f.clock, f.mailbox, f.wheels);
  hal::CanFrame short_frame = wheel_frame(0, 2, 25'000'000);
  short_frame.length = 6;
  hal::CanFrame other = wheel_frame(0, 9, 26'000'000);
  other.id = 0x200;
  hal::CanFrame extended = wheel_frame(0, 9, 27'000'000);
  extended.extended = true;
  f.bus.inbox = {wheel_frame(0, 0, 10'000'000), wheel_frame(10, 1, 20'000'000), short_frame, other, extended,
                 wheel_frame(30, 3, 40'000'000)};  // counter 1 -> 3: one frame lost
  f.drain(output);
  EXPECT_EQ(output.wheel_counters().frames, 3U);
  EXPECT_EQ(output.wheel_counters().malformed, 1U);
  EXPECT_EQ(output.wheel_counters().counter_gaps, 1U);
  EXPECT_EQ(output.wheel_counters().unmatched, 0U);
  ASSERT_NE(f.wheels.prior(), nullptr);
  // A live base: the frames keep their own (bus) stamps.
  EXPECT_EQ(f.wheels.prior()->odometry().newest_stamp_ns(), 40'000'000);
}

TEST(PoseOutput, PlayedFramesTakeTheRecordedStampsBack) {
  Fixture f;
  const std::vector<hal::CanFrame> recorded = {wheel_frame(0, 0, 5'000'000'000), wheel_frame(10, 1, 5'010'000'000),
                                               wheel_frame(20, 2, 5'020'000'000)};
  f.wheels.enable({}, hal::WheelGeometry{}, Eigen::Isometry3d::Identity(), &recorded);
  PoseOutput output(f.options, f.bus, f.clock, f.mailbox, f.wheels);
  // Received with bus stamps; the second is lost on the way, and one frame was never played.
  f.bus.inbox = {wheel_frame(0, 0, 7), wheel_frame(20, 2, 9), wheel_frame(99, 3, 11)};
  f.drain(output);
  EXPECT_EQ(output.wheel_counters().frames, 3U);
  EXPECT_EQ(output.wheel_counters().unmatched, 1U);
  EXPECT_EQ(f.wheels.prior()->odometry().newest_stamp_ns(), 5'020'000'000);
}

TEST(PoseOutput, WithoutWheelsFramesAreCountedButNotUsed) {
  Fixture f;
  PoseOutput output(f.options, f.bus, f.clock, f.mailbox, f.wheels);
  f.bus.inbox = {wheel_frame(0, 0, 10), wheel_frame(10, 1, 20)};
  f.drain(output);
  EXPECT_EQ(output.wheel_counters().frames, 2U);
  EXPECT_EQ(output.wheel_counters().unmatched, 0U);
  EXPECT_EQ(f.wheels.prior(), nullptr);
}

TEST(PoseOutput, SendsThePostedPoseAtItsRate) {
  Fixture f;
  PoseOutput output(f.options, f.bus, f.clock, f.mailbox, f.wheels);
  PoseSample sample;
  sample.T_map_base.translation() = Eigen::Vector3d(1.0, 2.0, 0.0);
  f.mailbox.post(sample, nullptr, std::nullopt);
  output.step();
  const auto cycles = output.pose_counters().pose_cycles;
  EXPECT_GE(cycles, 1U);
  f.clock.now += static_cast<std::int64_t>(1e9 / f.options.broadcast.pose_rate_hz);
  output.step();
  EXPECT_EQ(output.pose_counters().pose_cycles, cycles + 1);
  EXPECT_FALSE(f.bus.sent.empty());
}

TEST(PoseOutput, ADueCycleCarriesTheWheelFramesAlreadyQueued) {
  Fixture f;
  hal::WheelGeometry geometry;
  f.wheels.enable({}, geometry, Eigen::Isometry3d::Identity(), nullptr);
  PoseOutput output(f.options, f.bus, f.clock, f.mailbox, f.wheels);
  f.bus.inbox = {wheel_frame(0, 0, 10'000'000)};
  f.drain(output);
  PoseSample sample;
  sample.capture_ns = f.clock.now;
  f.mailbox.post(sample, nullptr, std::int64_t{10'000'000});
  f.clock.now += 1'000'000'000;  // a cycle is due
  // A burst the base sent while the output did not run: ten frames, 10 ticks each, queued.
  for (std::uint8_t i = 1; i <= 10; ++i) {
    f.bus.inbox.push_back(wheel_frame(10U * i, i, 10'000'000 + 10'000'000 * static_cast<std::int64_t>(i)));
  }
  f.bus.sent.clear();
  output.step();
  // The cycle sent in this step is moved on by all ten frames, as the burst's last one says.
  ASSERT_GE(f.bus.sent.size(), 5U);
  const auto xy_yaw = decode_pose_xy_yaw(f.bus.sent.front());
  ASSERT_TRUE(xy_yaw);
  const double expected_m = 100.0 * 2.0 * std::numbers::pi * geometry.radius_m / geometry.ticks_per_revolution;
  EXPECT_NEAR(xy_yaw->x_m, expected_m, 0.0015) << "the cycle went out before the queued wheel frames were taken in";
  EXPECT_TRUE(f.bus.inbox.empty());
}

TEST(PoseMailbox, ASampleOverwrittenBeforeDeliveryKeepsItsCorrection) {
  QueueBus bus;
  ManualClock clock;
  PoseBroadcaster broadcaster({}, bus, clock);
  PoseMailbox mailbox;
  Eigen::Isometry3d first = Eigen::Isometry3d::Identity();
  first.translation() = Eigen::Vector3d(0.5, 0.0, 0.0);
  Eigen::Isometry3d second = Eigen::Isometry3d::Identity();
  second.translation() = Eigen::Vector3d(0.0, 0.25, 0.0);
  mailbox.post(PoseSample{}, &first, std::int64_t{100});
  mailbox.post(PoseSample{}, &second, std::int64_t{200});
  std::optional<std::int64_t> wheel_stamp_ns;
  mailbox.deliver(broadcaster, wheel_stamp_ns);
  EXPECT_TRUE(broadcaster.T_map_odom().translation().isApprox(Eigen::Vector3d(0.5, 0.25, 0.0)));
  EXPECT_EQ(wheel_stamp_ns, 200);
  // Delivered once: a second delivery without a new sample applies nothing again.
  mailbox.deliver(broadcaster, wheel_stamp_ns);
  EXPECT_TRUE(broadcaster.T_map_odom().translation().isApprox(Eigen::Vector3d(0.5, 0.25, 0.0)));
}

TEST(LiveWheels, PriorWaitsForAWheelFrameAtOrAfterTheStamp) {
  LiveWheels wheels;
  wheels.enable({}, hal::WheelGeometry{}, Eigen::Isometry3d::Identity(), nullptr);
  MotionPrior prior;
  const auto always = [](std::int64_t) { return true; };
  (void)wheels.add(wheel_frame(0, 0, 0), 1);
  (void)wheels.add(wheel_frame(40, 1, 10'000'000), 2);
  EXPECT_FALSE(wheels.prior_for(5'000'000, std::chrono::milliseconds(0), always, prior)) << "first frame: no previous";
  (void)wheels.add(wheel_frame(80, 2, 20'000'000), 3);
  EXPECT_TRUE(wheels.prior_for(15'000'000, std::chrono::milliseconds(0), always, prior));
  EXPECT_GT(prior.T_previous_current.translation().norm(), 0.0);
}

}  // namespace
}  // namespace rankslam::nav
