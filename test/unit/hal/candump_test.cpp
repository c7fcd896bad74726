#include "rankslam/hal/candump.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

namespace rankslam::hal {
namespace {

TEST(Candump, ParsesStandardFrame) {
  const auto frame = parse_candump_line("(1700000000.033333) can0 101#0011223344556677");
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->stamp_ns, 1700000000033333000LL);
  EXPECT_EQ(frame->id, 0x101U);
  EXPECT_FALSE(frame->extended);
  ASSERT_EQ(frame->length, 8);
  EXPECT_EQ(frame->data[0], 0x00);
  EXPECT_EQ(frame->data[7], 0x77);
}

TEST(Candump, ParsesExtendedAndShortFrames) {
  const auto frame = parse_candump_line("(5.5) vcan0 18FF0102#AB");
  ASSERT_TRUE(frame.has_value());
  EXPECT_TRUE(frame->extended);
  EXPECT_EQ(frame->id, 0x18FF0102U);
  EXPECT_EQ(frame->stamp_ns, 5'500'000'000LL);
  EXPECT_EQ(frame->length, 1);
  EXPECT_EQ(frame->data[0], 0xAB);
  const auto empty = parse_candump_line("(1.000000) can0 123#");
  ASSERT_TRUE(empty.has_value());
  EXPECT_EQ(empty->length, 0);
}

TEST(Candump, RejectsMalformedLines) {
  for (const char* line : {"", "garbage", "(1.0) can0", "(1.0) can0 12#00", "(1.0) can0 101#0", "(1.0) can0 101#0G",
                           "(x.0) can0 101#00", "(1.0) can0 101#001122334455667788", "(1.0) can0 101#R"}) {
    EXPECT_FALSE(parse_candump_line(line).has_value()) << line;
  }
}

TEST(Candump, StampsMustFitAnInt64OfNanoseconds) {
  // The largest stamp whose nanoseconds fit, and the smallest beyond it.
  const auto largest = parse_candump_line("(9223372036.854775807) can0 101#00");
  ASSERT_TRUE(largest.has_value());
  EXPECT_EQ(largest->stamp_ns, std::numeric_limits<std::int64_t>::max());
  for (const char* line : {"(9223372036.854775808) can0 101#00", "(99999999999.000000) can0 101#00",
                           "(9223372037.000000) can0 101#00", "(-1.000000) can0 101#00", "(1.-5) can0 101#00",
                           "(.5) can0 101#00"}) {
    EXPECT_FALSE(parse_candump_line(line).has_value()) << line;
  }
  const auto zero = parse_candump_line("(0.000001) can0 101#00");
  ASSERT_TRUE(zero.has_value());
  EXPECT_EQ(zero->stamp_ns, 1000);
}

// Found by fuzz_candump: a stamp with trailing bytes inside its field, and identifiers beyond
// 11 or 29 bits, were accepted.
TEST(Candump, StampsAndIdentifiersMustBeWholeAndInRange) {
  for (const char* line : {"(17x.5) can0 101#00", "(17.5x) can0 101#00", "(1.0) can0 800#00", "(1.0) can0 FFF#00",
                           "(1.0) can0 20000000#00", "(1.0) can0 31462578#DEADBE"}) {
    EXPECT_FALSE(parse_candump_line(line).has_value()) << line;
  }
  for (const char* line : {"(1.0) can0 7FF#00", "(1.0) can0 1FFFFFFF#00"}) {
    EXPECT_TRUE(parse_candump_line(line).has_value()) << line;
  }
}

TEST(Candump, FormatRoundTrips) {
  CanFrame frame;
  frame.stamp_ns = 1700000001'250000000LL;
  frame.id = 0x7FF;
  frame.length = 3;
  frame.data = {0xDE, 0xAD, 0x01};
  const std::string line = format_candump_line(frame, "can1");
  EXPECT_EQ(line, "(1700000001.250000) can1 7FF#DEAD01");
  const auto parsed = parse_candump_line(line);
  ASSERT_TRUE(parsed.has_value());
  EXPECT_EQ(parsed->id, frame.id);
  EXPECT_EQ(parsed->stamp_ns, frame.stamp_ns);
  EXPECT_EQ(parsed->length, frame.length);
  EXPECT_EQ(parsed->data, frame.data);
}

}  // namespace
}  // namespace rankslam::hal
