#include "rankslam/nav/wheel_frame.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace rankslam::nav {
namespace {

TEST(WheelFrame, RoundTripsAllFields) {
  WheelTicks ticks;
  ticks.left_ticks = 0x123456;
  ticks.right_ticks = 0xFEDCBA;
  ticks.rolling_counter = 200;
  ticks.right_fault = true;
  const hal::CanFrame frame = encode_wheel_ticks(ticks, 0x101, 42);
  EXPECT_EQ(frame.id, 0x101U);
  EXPECT_EQ(frame.length, 8);
  EXPECT_EQ(frame.stamp_ns, 42);
  // Little-endian layout as documented in the DBC.
  EXPECT_EQ(frame.data[0], 0x56);
  EXPECT_EQ(frame.data[2], 0x12);
  EXPECT_EQ(frame.data[3], 0xBA);
  EXPECT_EQ(frame.data[5], 0xFE);
  EXPECT_EQ(frame.data[6], 200);
  EXPECT_EQ(frame.data[7], 0x02);
  const auto decoded = decode_wheel_ticks(frame);
  ASSERT_TRUE(decoded.has_value());
  EXPECT_EQ(decoded->left_ticks, ticks.left_ticks);
  EXPECT_EQ(decoded->right_ticks, ticks.right_ticks);
  EXPECT_EQ(decoded->rolling_counter, 200);
  EXPECT_FALSE(decoded->left_fault);
  EXPECT_TRUE(decoded->right_fault);
}

TEST(WheelFrame, CountersWrapAt24Bits) {
  WheelTicks ticks;
  ticks.left_ticks = kWheelTickModulus + 5;
  const auto decoded = decode_wheel_ticks(encode_wheel_ticks(ticks, 0x101, 0));
  ASSERT_TRUE(decoded.has_value());
  EXPECT_EQ(decoded->left_ticks, 5U);
  EXPECT_EQ(wheel_tick_delta(kWheelTickModulus - 3, 4), 7);
  EXPECT_EQ(wheel_tick_delta(4, kWheelTickModulus - 3), -7);
  EXPECT_EQ(wheel_tick_delta(100, 100), 0);
}

TEST(WheelFrame, RejectsWrongLength) {
  hal::CanFrame frame;
  frame.length = 7;
  EXPECT_FALSE(decode_wheel_ticks(frame).has_value());
}

TEST(WheelFrame, MalformedWheelFramesAreCountedAndTheFirstNamed) {
  std::vector<hal::CanFrame> frames;
  for (int i = 0; i < 6; ++i) frames.push_back(encode_wheel_ticks({}, 0x101, 1'000'000'000LL + i * 10'000'000LL));
  frames[1].length = 2;
  frames[2].id = 0x102;  // another frame, any length
  frames[2].length = 1;
  frames[3].extended = true;  // an extended identifier is not the wheel frame
  frames[3].length = 3;
  frames[4].length = 0;
  EXPECT_EQ(describe_malformed_wheel_frames(frames, 0x101),
            "2 wheel frames (identifier 0x101) are not 8 bytes long and are not used: 1.010000 s with 2 bytes, "
            "1.040000 s with 0 bytes");
  frames[1].length = kWheelTicksLength;
  frames[4].length = kWheelTicksLength;
  EXPECT_EQ(describe_malformed_wheel_frames(frames, 0x101), "");
  for (auto& frame : frames) frame.length = 5;
  EXPECT_NE(describe_malformed_wheel_frames(frames, 0x101).find("4 wheel frames"), std::string::npos);
  EXPECT_NE(describe_malformed_wheel_frames(frames, 0x101).find("1.040000 s with 5 bytes, ..."), std::string::npos);
}

}  // namespace
}  // namespace rankslam::nav
