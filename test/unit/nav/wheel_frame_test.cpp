#include "rankslam/nav/wheel_frame.hpp"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace rankslam::nav
