// SocketCanBus on the host: set-up validation and the messages for a kernel without SocketCAN
// or without the interface. The bus itself is tested on a real kernel in test/vm.

#include "rankslam/socketcan/socketcan_bus.hpp"

#include <gtest/gtest.h>

#include <sys/socket.h>
#include <unistd.h>

#include <linux/can.h>

namespace rankslam::socketcan {
namespace {

using namespace std::chrono_literals;

SocketCanOptions named(std::string name) {
  SocketCanOptions options;
  options.interface_name = std::move(name);
  return options;
}

bool kernel_has_can() {
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) return false;
  ::close(fd);
  return true;
}

TEST(SocketCanBus, RefusesBadOptionsBeforeTouchingTheKernel) {
  EXPECT_NE(SocketCanBus(named("")).open().find("interface name"), std::string::npos);
  EXPECT_NE(SocketCanBus(named("a_name_far_too_long0")).open().find("interface name"), std::string::npos);

  SocketCanOptions many = named("can0");
  many.filters.resize(SocketCanBus::kMaxFilters + 1);
  EXPECT_NE(SocketCanBus(many).open().find("filters given"), std::string::npos);

  SocketCanOptions wide = named("can0");
  wide.filters.push_back({.id = 0x12345, .mask = 0x7FF, .extended = false});
  EXPECT_NE(SocketCanBus(wide).open().find("11-bit"), std::string::npos);
  wide.filters.back() = {.id = 0x20000000, .mask = 0, .extended = true};
  EXPECT_NE(SocketCanBus(wide).open().find("29-bit"), std::string::npos);

  SocketCanOptions negative = named("can0");
  negative.receive_buffer_bytes = -1;
  EXPECT_NE(SocketCanBus(negative).open().find("receive_buffer_bytes"), std::string::npos);
}

TEST(SocketCanBus, OpenSaysWhatIsMissing) {
  SocketCanBus bus(named("rankslamnone0"));
  const std::string error = bus.open();
  if (kernel_has_can()) {
    EXPECT_NE(error.find("rankslamnone0: no such interface"), std::string::npos) << error;
  } else {
    EXPECT_NE(error.find("no CAN raw sockets"), std::string::npos) << error;
    EXPECT_NE(error.find("can-raw"), std::string::npos) << error;
  }
  EXPECT_FALSE(bus.is_open());
}

TEST(SocketCanBus, AnUnopenedBusReportsFaultsWithoutBlocking) {
  SocketCanBus bus(named("can0"));
  hal::CanFrame frame;
  EXPECT_EQ(bus.receive(frame, 1000ms), hal::ReadStatus::kFault);
  EXPECT_EQ(bus.send(frame), hal::ReadStatus::kFault);
  EXPECT_EQ(bus.statistics().faults, 2U);
}

TEST(SocketCanBus, InvalidFramesAreCountedAsSuch) {
  SocketCanBus bus(named("can0"));
  hal::CanFrame frame;
  frame.id = 0x800;
  EXPECT_EQ(bus.send(frame), hal::ReadStatus::kFault);
  frame.id = 0x7FF;
  frame.length = 9;
  EXPECT_EQ(bus.send(frame), hal::ReadStatus::kFault);
  EXPECT_EQ(bus.statistics().tx_invalid, 2U);
}

}  // namespace
}  // namespace rankslam::socketcan
