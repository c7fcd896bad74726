#include "rankslam/socketcan/error_frame.hpp"

#include <gtest/gtest.h>

#include <linux/can.h>
#include <linux/can/error.h>

namespace rankslam::socketcan {
namespace {

using Data = std::array<std::uint8_t, 8>;

Data controller(std::uint8_t state, std::uint8_t tx_errors = 0, std::uint8_t rx_errors = 0) {
  return {0, state, 0, 0, 0, 0, tx_errors, rx_errors};
}

TEST(ErrorFrame, StateTransitionsAreCountedOncePerTransition) {
  hal::CanBusStatistics stats;
  // Up: warning, warning again (a repeat, not a transition), passive.
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_TX_WARNING), stats);
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_RX_WARNING), stats);
  EXPECT_EQ(stats.error_warning, 1U);
  EXPECT_TRUE(stats.error_warning_now);
  EXPECT_FALSE(stats.error_passive);
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_RX_PASSIVE), stats);
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_TX_PASSIVE), stats);
  EXPECT_EQ(stats.error_passive_entered, 1U);
  EXPECT_TRUE(stats.error_passive);
  // Down: back to warning, then active.
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_TX_WARNING), stats);
  EXPECT_FALSE(stats.error_passive);
  EXPECT_TRUE(stats.error_warning_now);
  EXPECT_EQ(stats.error_warning, 1U);  // it never left warning level
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_ACTIVE), stats);
  EXPECT_FALSE(stats.error_passive);
  EXPECT_FALSE(stats.error_warning_now);
  EXPECT_EQ(stats.error_frames, 6U);
}

TEST(ErrorFrame, OverflowReportsCarryNoState) {
  hal::CanBusStatistics stats;
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_TX_PASSIVE), stats);
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_RX_OVERFLOW), stats);
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_TX_OVERFLOW), stats);
  EXPECT_EQ(stats.controller_overflows, 2U);
  EXPECT_TRUE(stats.error_passive);
}

TEST(ErrorFrame, BusOffUntilRestart) {
  hal::CanBusStatistics stats;
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, controller(CAN_ERR_CRTL_TX_PASSIVE), stats);
  auto effect = apply_error_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {}, stats);
  EXPECT_TRUE(effect.bus_off);
  EXPECT_FALSE(effect.restarted);
  EXPECT_TRUE(stats.bus_off_now);
  effect = apply_error_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {}, stats);  // reported again
  EXPECT_TRUE(effect.bus_off);
  EXPECT_EQ(stats.bus_off, 1U);
  effect = apply_error_frame(CAN_ERR_FLAG | CAN_ERR_RESTARTED, {}, stats);
  EXPECT_TRUE(effect.restarted);
  EXPECT_FALSE(stats.bus_off_now);
  EXPECT_FALSE(stats.error_passive);
  EXPECT_EQ(stats.restarts, 1U);
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {}, stats);
  EXPECT_EQ(stats.bus_off, 2U);
}

TEST(ErrorFrame, EveryClassInOneFrameIsCounted) {
  hal::CanBusStatistics stats;
  const std::uint32_t all = CAN_ERR_FLAG | CAN_ERR_TX_TIMEOUT | CAN_ERR_LOSTARB | CAN_ERR_PROT | CAN_ERR_TRX |
                            CAN_ERR_ACK | CAN_ERR_BUSERROR | CAN_ERR_CNT;
  (void)apply_error_frame(all, {3, 0, CAN_ERR_PROT_BIT, CAN_ERR_PROT_LOC_ACK, CAN_ERR_TRX_CANL_NO_WIRE, 0, 200, 7},
                          stats);
  EXPECT_EQ(stats.error_frames, 1U);
  EXPECT_EQ(stats.tx_timeouts, 1U);
  EXPECT_EQ(stats.arbitration_lost, 1U);
  EXPECT_EQ(stats.protocol_errors, 1U);
  EXPECT_EQ(stats.transceiver_errors, 1U);
  EXPECT_EQ(stats.no_ack, 1U);
  EXPECT_EQ(stats.bus_errors, 1U);
  EXPECT_EQ(stats.tx_error_counter, 200);
  EXPECT_EQ(stats.rx_error_counter, 7);
  EXPECT_EQ(stats.bus_off, 0U);
  EXPECT_FALSE(stats.error_passive);
}

TEST(ErrorFrame, CountersWithoutTheCountFlagAreIgnored) {
  hal::CanBusStatistics stats;
  stats.tx_error_counter = 5;
  (void)apply_error_frame(CAN_ERR_FLAG | CAN_ERR_ACK, {0, 0, 0, 0, 0, 0, 99, 99}, stats);
  EXPECT_EQ(stats.tx_error_counter, 5);
  EXPECT_EQ(stats.rx_error_counter, 0);
}

}  // namespace
}  // namespace rankslam::socketcan
