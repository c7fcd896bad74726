#include "rankslam/replay/replay_can_bus.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace rankslam::replay {
namespace {

using std::chrono::milliseconds;

constexpr std::uint32_t kWheelId = 0x101;
constexpr std::uint32_t kOtherId = 0x200;

hal::CanFrame can_frame(std::int64_t stamp_ns, std::uint32_t id, bool extended = false) {
  hal::CanFrame frame;
  frame.stamp_ns = stamp_ns;
  frame.id = id;
  frame.extended = extended;
  frame.length = 8;
  frame.data[0] = static_cast<std::uint8_t>(stamp_ns);
  return frame;
}

/// The stamps receive() hands out until it stops saying kOk.
std::vector<std::int64_t> drain(ReplayCanBus& bus, hal::ReadStatus& last) {
  std::vector<std::int64_t> stamps;
  hal::CanFrame frame;
  while ((last = bus.receive(frame, milliseconds(0))) == hal::ReadStatus::kOk) stamps.push_back(frame.stamp_ns);
  return stamps;
}

using Stamps = std::vector<std::int64_t>;

TEST(ReplayCanBus, ReleasesUpToTheFirstWheelFrameAtOrAfterTheStamp) {
  // Wheels every 10, another identifier in between, an extended frame with the wheel identifier.
  const std::vector<hal::CanFrame> frames = {can_frame(0, kWheelId),  can_frame(5, kOtherId),
                                             can_frame(10, kWheelId), can_frame(15, kWheelId, true),
                                             can_frame(20, kWheelId), can_frame(25, kOtherId),
                                             can_frame(30, kWheelId)};
  ReplayCanBus bus(frames, {kWheelId});
  ASSERT_EQ(bus.open(), "");
  hal::ReadStatus last{};
  EXPECT_EQ(drain(bus, last), Stamps{}) << "nothing before the first camera frame";
  EXPECT_EQ(last, hal::ReadStatus::kNoData);

  bus.release_through(10);  // a wheel frame exactly at the stamp closes the interval
  EXPECT_EQ(drain(bus, last), (Stamps{0, 5, 10}));
  EXPECT_EQ(last, hal::ReadStatus::kNoData);

  // The extended frame at 15 is not a wheel frame: the release goes on to the one at 20.
  bus.release_through(12);
  EXPECT_EQ(drain(bus, last), (Stamps{15, 20}));

  bus.release_through(26);
  EXPECT_EQ(drain(bus, last), (Stamps{25, 30}));
  EXPECT_EQ(last, hal::ReadStatus::kEndOfStream);
  EXPECT_EQ(bus.statistics().frames_rx, frames.size());
}

TEST(ReplayCanBus, ReleasesAtLeastOneFrameWhileAnyIsLeft) {
  // Two camera frames between the same wheel frames: the second still takes the next frame,
  // as replay's wheel pacing always has.
  const std::vector<hal::CanFrame> frames = {can_frame(0, kWheelId), can_frame(10, kWheelId), can_frame(20, kWheelId)};
  ReplayCanBus bus(frames, {kWheelId});
  ASSERT_EQ(bus.open(), "");
  hal::ReadStatus last{};
  bus.release_through(3);
  EXPECT_EQ(drain(bus, last), (Stamps{0, 10}));
  bus.release_through(4);
  EXPECT_EQ(drain(bus, last), (Stamps{20}));
  EXPECT_EQ(last, hal::ReadStatus::kEndOfStream);
}

TEST(ReplayCanBus, ReleasesEverythingLeftWhenNoWheelFrameReachesTheStamp) {
  const std::vector<hal::CanFrame> frames = {can_frame(0, kWheelId), can_frame(10, kOtherId), can_frame(20, kOtherId)};
  ReplayCanBus bus(frames, {kWheelId});
  ASSERT_EQ(bus.open(), "");
  hal::ReadStatus last{};
  bus.release_through(5);
  EXPECT_EQ(drain(bus, last), (Stamps{0, 10, 20}));
  EXPECT_EQ(last, hal::ReadStatus::kEndOfStream);
  EXPECT_EQ(bus.released(), frames.size());
}

TEST(ReplayCanBus, TheWheelIdentifierIsTheOneConfigured) {
  const std::vector<hal::CanFrame> frames = {can_frame(0, kWheelId), can_frame(10, kWheelId), can_frame(20, kOtherId)};
  ReplayCanBus bus(frames, {kOtherId});
  ASSERT_EQ(bus.open(), "");
  hal::ReadStatus last{};
  bus.release_through(5);
  EXPECT_EQ(drain(bus, last), (Stamps{0, 10, 20}));
}

TEST(ReplayCanBus, RefusesFramesOutOfStampOrder) {
  const std::vector<hal::CanFrame> frames = {can_frame(0, kWheelId), can_frame(20, kWheelId), can_frame(10, kWheelId)};
  ReplayCanBus bus(frames, {kWheelId});
  EXPECT_NE(bus.open(), "");
}

TEST(ReplayCanBus, CountsSentFramesAndFaultsWhenClosed) {
  const std::vector<hal::CanFrame> frames = {can_frame(0, kWheelId)};
  ReplayCanBus bus(frames, {kWheelId});
  hal::CanFrame frame;
  EXPECT_EQ(bus.receive(frame, milliseconds(0)), hal::ReadStatus::kFault);
  ASSERT_EQ(bus.open(), "");
  EXPECT_EQ(bus.send(can_frame(1, 0x300)), hal::ReadStatus::kOk);
  EXPECT_EQ(bus.statistics().frames_tx, 1U);
  bus.close();
  EXPECT_EQ(bus.send(can_frame(2, 0x300)), hal::ReadStatus::kFault);
}

}  // namespace
}  // namespace rankslam::replay
