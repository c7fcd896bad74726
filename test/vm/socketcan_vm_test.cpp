// SocketCanBus against the kernel's real SocketCAN stack on vcan0 (inside the VM).
//
// vcan is a software interface: it delivers every frame at once and never has a controller,
// so error frames here are injected by a peer socket and travel the kernel's real error-frame
// path (CAN_ERR_FLAG, CAN_RAW_ERR_FILTER). A full transmit queue is made with a netem queueing
// discipline holding frames, as a controller that cannot win the bus does.

#include "allocation_counter.hpp"
#include "rankslam/hal/candump.hpp"
#include "rankslam/nav/wheel_frame.hpp"
#include "rankslam/socketcan/socketcan_bus.hpp"
#include "vm_support.hpp"

#include <gtest/gtest.h>

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <csignal>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace rankslam::socketcan {
namespace {

using namespace std::chrono_literals;
using hal::ReadStatus;

constexpr const char* kInterface = "vcan0";

std::int64_t monotonic_ns() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * 1'000'000'000 + now.tv_nsec;
}

// A second raw socket on the bus, independent of the driver under test.
class PeerSocket {
 public:
  PeerSocket() {
    fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
    if (fd_ < 0) return;
    sockaddr_can address{};
    address.can_family = AF_CAN;
    address.can_ifindex = static_cast<int>(if_nametoindex(kInterface));
    if (::bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) < 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~PeerSocket() {
    if (fd_ >= 0) ::close(fd_);
  }
  PeerSocket(const PeerSocket&) = delete;
  PeerSocket& operator=(const PeerSocket&) = delete;

  [[nodiscard]] bool ok() const { return fd_ >= 0; }

  bool send(canid_t can_id, std::vector<std::uint8_t> data) {
    can_frame frame{};
    frame.can_id = can_id;
    frame.len = static_cast<std::uint8_t>(data.size());
    std::memcpy(frame.data, data.data(), data.size());
    return ::write(fd_, &frame, sizeof(frame)) == static_cast<ssize_t>(sizeof(frame));
  }

  bool send_error(canid_t classes, std::array<std::uint8_t, 8> data) {
    can_frame frame{};
    frame.can_id = CAN_ERR_FLAG | classes;
    frame.len = CAN_ERR_DLC;
    std::memcpy(frame.data, data.data(), data.size());
    return ::write(fd_, &frame, sizeof(frame)) == static_cast<ssize_t>(sizeof(frame));
  }

  std::optional<can_frame> receive(int timeout_ms) {
    pollfd request{.fd = fd_, .events = POLLIN, .revents = 0};
    if (::poll(&request, 1, timeout_ms) <= 0) return std::nullopt;
    can_frame frame{};
    if (::read(fd_, &frame, sizeof(frame)) != static_cast<ssize_t>(sizeof(frame))) return std::nullopt;
    return frame;
  }

 private:
  int fd_ = -1;
};

SocketCanOptions vcan_options(std::vector<CanIdFilter> filters = {}) {
  SocketCanOptions options;
  options.interface_name = kInterface;
  options.filters = std::move(filters);
  options.reopen_interval = 0ms;
  return options;
}

bool vcan_up() { return vm_test::shell(std::string("ip link set ") + kInterface + " up") == 0; }

// Puts vcan0 back as /init left it, whatever a test did to it.
struct RestoreInterface {
  ~RestoreInterface() {
    if (if_nametoindex(kInterface) == 0) {
      (void)vm_test::shell(std::string("ip link add dev ") + kInterface + " type vcan");
    }
    (void)vm_test::shell(std::string("tc qdisc del dev ") + kInterface + " root 2>/dev/null");
    (void)vcan_up();
  }
};

class SocketCanVm : public ::testing::Test {
 protected:
  void SetUp() override {
    const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
    const bool have_can = fd >= 0;
    if (fd >= 0) ::close(fd);
    RANKSLAM_VM_REQUIRE(have_can, "socket(PF_CAN) fails: this kernel has no SocketCAN");
    RANKSLAM_VM_REQUIRE(if_nametoindex(kInterface) != 0, "no " << kInterface << " interface");
  }
};

TEST_F(SocketCanVm, OpenNamesAMissingInterface) {
  SocketCanOptions options;
  options.interface_name = "nosuchcan0";
  SocketCanBus bus(options);
  const std::string error = bus.open();
  EXPECT_NE(error.find("nosuchcan0"), std::string::npos) << error;
  EXPECT_NE(error.find("no such interface"), std::string::npos) << error;
  hal::CanFrame frame;
  EXPECT_EQ(bus.receive(frame, 10ms), ReadStatus::kFault);
}

TEST_F(SocketCanVm, OpenRefusesFiltersOutsideTheIdentifierRange) {
  SocketCanBus bus(vcan_options({{.id = 0x800, .mask = 0x7FF, .extended = false}}));
  const std::string error = bus.open();
  EXPECT_NE(error.find("11-bit"), std::string::npos) << error;
}

TEST_F(SocketCanVm, ReceivesAFrameWithItsKernelStampOnTheMonotonicClock) {
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  PeerSocket peer;
  ASSERT_TRUE(peer.ok());

  const std::int64_t before_ns = monotonic_ns();
  ASSERT_TRUE(peer.send(0x123, {0xDE, 0xAD, 0xBE, 0xEF, 0x01, 0x02, 0x03, 0x04}));
  hal::CanFrame frame;
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  const std::int64_t after_ns = monotonic_ns();

  EXPECT_EQ(frame.id, 0x123U);
  EXPECT_FALSE(frame.extended);
  ASSERT_EQ(frame.length, 8);
  EXPECT_EQ(frame.data, (std::array<std::uint8_t, 8>{0xDE, 0xAD, 0xBE, 0xEF, 0x01, 0x02, 0x03, 0x04}));
  // The kernel stamped the frame between the send and our return. The realtime-to-monotonic
  // conversion is exact up to the few microseconds between reading the two clocks.
  EXPECT_GE(frame.stamp_ns, before_ns - 1'000'000);
  EXPECT_LE(frame.stamp_ns, after_ns + 1'000'000);
  EXPECT_EQ(bus.statistics().frames_rx, 1U);
  std::printf("kernel stamp %.3f ms after the send, read %.3f ms after the send\n",
              static_cast<double>(frame.stamp_ns - before_ns) * 1e-6, static_cast<double>(after_ns - before_ns) * 1e-6);
}

TEST_F(SocketCanVm, ReceivesExtendedIdentifiersAndShortFrames) {
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  PeerSocket peer;
  ASSERT_TRUE(peer.send(0x1ABCDE12 | CAN_EFF_FLAG, {0x11, 0x22, 0x33}));
  ASSERT_TRUE(peer.send(0x7FF, {}));
  hal::CanFrame frame;
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_TRUE(frame.extended);
  EXPECT_EQ(frame.id, 0x1ABCDE12U);
  ASSERT_EQ(frame.length, 3);
  EXPECT_EQ(frame.data[2], 0x33);
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_FALSE(frame.extended);
  EXPECT_EQ(frame.id, 0x7FFU);
  EXPECT_EQ(frame.length, 0);
}

TEST_F(SocketCanVm, FiltersDeliverOnlyTheListedDataFrames) {
  SocketCanBus bus(vcan_options({
      {.id = 0x101, .mask = 0x7FF, .extended = false},
      {.id = 0x18FF0000, .mask = 0x1FFF0000, .extended = true},
  }));
  ASSERT_EQ(bus.open(), "");
  PeerSocket peer;
  ASSERT_TRUE(peer.send(0x100, {1}));
  ASSERT_TRUE(peer.send(0x101 | CAN_EFF_FLAG, {2}));  // same low bits, but extended
  ASSERT_TRUE(peer.send(0x101 | CAN_RTR_FLAG, {}));   // remote request for 0x101
  ASSERT_TRUE(peer.send(0x101, {3}));
  ASSERT_TRUE(peer.send(0x18FE1234 | CAN_EFF_FLAG, {4}));
  ASSERT_TRUE(peer.send(0x18FF1234 | CAN_EFF_FLAG, {5}));
  ASSERT_TRUE(peer.send(0x201, {6}));

  hal::CanFrame frame;
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x101U);
  EXPECT_FALSE(frame.extended);
  EXPECT_EQ(frame.data[0], 3);
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x18FF1234U);
  EXPECT_TRUE(frame.extended);
  EXPECT_EQ(frame.data[0], 5);
  EXPECT_EQ(bus.receive(frame, 200ms), ReadStatus::kTimeout);
  EXPECT_EQ(bus.statistics().frames_rx, 2U);
}

TEST_F(SocketCanVm, WheelTickFramesArriveAndDecode) {
  constexpr std::uint32_t kWheelId = 0x101;  // BO_ 257 WheelTicks in deploy/can/rankslam.dbc
  SocketCanBus bus(vcan_options({{.id = kWheelId, .mask = 0x7FF, .extended = false}}));
  ASSERT_EQ(bus.open(), "");
  PeerSocket peer;

  std::vector<nav::WheelTicks> sent;
  for (std::uint32_t i = 0; i < 20; ++i) {
    // Counters cross the 24-bit wrap half-way through.
    const nav::WheelTicks ticks{.left_ticks = (nav::kWheelTickModulus - 30 + 3 * i) % nav::kWheelTickModulus,
                                .right_ticks = 1000 + 7 * i,
                                .rolling_counter = static_cast<std::uint8_t>(250 + i),
                                .left_fault = i == 5,
                                .right_fault = i == 6};
    const hal::CanFrame encoded = nav::encode_wheel_ticks(ticks, kWheelId, 0);
    ASSERT_TRUE(peer.send(encoded.id, std::vector<std::uint8_t>(encoded.data.begin(), encoded.data.begin() + encoded.length)));
    sent.push_back(ticks);
  }
  std::optional<nav::WheelTicks> previous;
  for (const auto& expected : sent) {
    hal::CanFrame frame;
    ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
    const auto decoded = nav::decode_wheel_ticks(frame);
    ASSERT_TRUE(decoded.has_value());
    EXPECT_EQ(decoded->left_ticks, expected.left_ticks);
    EXPECT_EQ(decoded->right_ticks, expected.right_ticks);
    EXPECT_EQ(decoded->rolling_counter, expected.rolling_counter);
    EXPECT_EQ(decoded->left_fault, expected.left_fault);
    EXPECT_EQ(decoded->right_fault, expected.right_fault);
    if (previous) {
      EXPECT_EQ(nav::wheel_tick_delta(previous->left_ticks, decoded->left_ticks), 3);
      EXPECT_EQ(static_cast<std::uint8_t>(decoded->rolling_counter - previous->rolling_counter), 1);
    }
    previous = decoded;
  }
}

// Starts candump on vcan0 for one frame with identifier `id`, writing its -L log to `path`.
pid_t start_candump(const std::string& path, std::uint32_t id) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  char filter[64];
  std::snprintf(filter, sizeof(filter), "%s,%03X:7FF", kInterface, id);
  std::string program = "candump";
  std::string log_format = "-L";
  std::string count = "-n";
  std::string one = "1";
  std::string timeout = "-T";
  std::string timeout_ms = "10000";
  char* argv[] = {program.data(), log_format.data(), count.data(), one.data(),
                  timeout.data(), timeout_ms.data(), filter, nullptr};
  pid_t pid = -1;
  if (posix_spawnp(&pid, "candump", &actions, nullptr, argv, environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

TEST_F(SocketCanVm, SentFramesAreSeenByASecondSocketAndByCandump) {
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  PeerSocket peer;
  const char* tmp = std::getenv("TMPDIR");
  const std::string log_path = std::string(tmp != nullptr ? tmp : "/tmp") + "/candump-socketcan-vm.log";
  const pid_t candump = start_candump(log_path, 0x321);
  ASSERT_GT(candump, 0) << "cannot start candump (can-utils)";

  hal::CanFrame out;
  out.id = 0x321;
  out.length = 6;
  out.data = {0x10, 0x20, 0x30, 0x40, 0x50, 0x60, 0, 0};
  // candump binds its socket some time after it starts; send until it has seen one frame.
  int status = 0;
  bool candump_done = false;
  int sent = 0;
  for (int attempt = 0; attempt < 100 && !candump_done; ++attempt) {
    ASSERT_EQ(bus.send(out), ReadStatus::kOk);
    ++sent;
    const auto seen = peer.receive(2000);
    ASSERT_TRUE(seen.has_value()) << "the second socket did not see frame " << sent;
    EXPECT_EQ(seen->can_id, 0x321U);
    ASSERT_EQ(seen->len, 6);
    EXPECT_EQ(std::memcmp(seen->data, out.data.data(), 6), 0);
    std::this_thread::sleep_for(50ms);
    candump_done = ::waitpid(candump, &status, WNOHANG) == candump;
  }
  if (!candump_done) {
    ::kill(candump, SIGKILL);
    ::waitpid(candump, &status, 0);
    FAIL() << "candump saw none of " << sent << " frames";
  }
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
  EXPECT_EQ(bus.statistics().frames_tx, static_cast<std::uint64_t>(sent));

  std::ifstream log(log_path);
  std::string line;
  ASSERT_TRUE(std::getline(log, line)) << "candump wrote nothing";
  std::printf("candump: %s\n", line.c_str());
  const auto parsed = hal::parse_candump_line(line);
  ASSERT_TRUE(parsed.has_value()) << line;
  EXPECT_EQ(parsed->id, out.id);
  EXPECT_EQ(parsed->length, out.length);
  EXPECT_EQ(parsed->data, out.data);
  EXPECT_NE(line.find(kInterface), std::string::npos);
}

TEST_F(SocketCanVm, AnIdleBusTimesOutWithinTheWaitBudget) {
  SocketCanBus bus(vcan_options({{.id = 0x7AB, .mask = 0x7FF, .extended = false}}));
  ASSERT_EQ(bus.open(), "");
  hal::CanFrame frame;
  EXPECT_EQ(bus.receive(frame, 0ms), ReadStatus::kNoData);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(bus.receive(frame, 150ms), ReadStatus::kTimeout);
  const auto elapsed = std::chrono::steady_clock::now() - start;
  // It waited, and it did not block far past its budget (generous bound for an emulated CPU).
  EXPECT_GE(elapsed, 150ms);
  EXPECT_LT(elapsed, 150ms + 1500ms);
}

TEST_F(SocketCanVm, ErrorFramesUpdateTheCountersAndBusOffIsAFault) {
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  SocketCanOptions quiet_options = vcan_options();
  quiet_options.error_frames = false;
  SocketCanBus quiet(quiet_options);
  ASSERT_EQ(quiet.open(), "");
  PeerSocket peer;
  hal::CanFrame frame;

  // Warning level with error counters, then lost arbitration, then a data frame: the error
  // frames are folded into the counters and the data frame is what receive() returns.
  ASSERT_TRUE(peer.send_error(CAN_ERR_CRTL | CAN_ERR_CNT, {0, CAN_ERR_CRTL_TX_WARNING, 0, 0, 0, 0, 97, 12}));
  ASSERT_TRUE(peer.send_error(CAN_ERR_LOSTARB, {5, 0, 0, 0, 0, 0, 0, 0}));
  ASSERT_TRUE(peer.send(0x42, {1, 2}));
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x42U);
  auto stats = bus.statistics();
  EXPECT_EQ(stats.error_frames, 2U);
  EXPECT_EQ(stats.error_warning, 1U);
  EXPECT_TRUE(stats.error_warning_now);
  EXPECT_FALSE(stats.error_passive);
  EXPECT_EQ(stats.arbitration_lost, 1U);
  EXPECT_EQ(stats.tx_error_counter, 97);
  EXPECT_EQ(stats.rx_error_counter, 12);

  // Error-passive, then the other error classes.
  ASSERT_TRUE(peer.send_error(CAN_ERR_CRTL | CAN_ERR_CNT, {0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 130, 12}));
  ASSERT_TRUE(peer.send_error(CAN_ERR_PROT | CAN_ERR_BUSERROR, {0, 0, CAN_ERR_PROT_STUFF, CAN_ERR_PROT_LOC_DATA, 0, 0, 0, 0}));
  ASSERT_TRUE(peer.send_error(CAN_ERR_ACK, {}));
  ASSERT_TRUE(peer.send_error(CAN_ERR_TRX, {0, 0, 0, 0, CAN_ERR_TRX_CANH_NO_WIRE, 0, 0, 0}));
  ASSERT_TRUE(peer.send_error(CAN_ERR_TX_TIMEOUT, {}));
  ASSERT_TRUE(peer.send_error(CAN_ERR_CRTL, {0, CAN_ERR_CRTL_RX_OVERFLOW, 0, 0, 0, 0, 0, 0}));
  EXPECT_EQ(bus.receive(frame, 300ms), ReadStatus::kTimeout);
  stats = bus.statistics();
  EXPECT_EQ(stats.error_frames, 8U);
  EXPECT_TRUE(stats.error_passive);
  EXPECT_EQ(stats.error_passive_entered, 1U);
  EXPECT_EQ(stats.tx_error_counter, 130);
  EXPECT_EQ(stats.protocol_errors, 1U);
  EXPECT_EQ(stats.bus_errors, 1U);
  EXPECT_EQ(stats.no_ack, 1U);
  EXPECT_EQ(stats.transceiver_errors, 1U);
  EXPECT_EQ(stats.tx_timeouts, 1U);
  EXPECT_EQ(stats.controller_overflows, 1U);
  EXPECT_TRUE(stats.error_passive);  // an overflow report carries no state

  // Bus-off is a fault, and so is an empty wait while the controller stays off.
  ASSERT_TRUE(peer.send_error(CAN_ERR_BUSOFF, {}));
  EXPECT_EQ(bus.receive(frame, 2000ms), ReadStatus::kFault);
  EXPECT_TRUE(bus.statistics().bus_off_now);
  EXPECT_EQ(bus.statistics().bus_off, 1U);
  EXPECT_EQ(bus.receive(frame, 100ms), ReadStatus::kFault);
  EXPECT_TRUE(bus.is_open());  // the socket stays: the restart arrives through it

  // The controller restarts: data flows again.
  ASSERT_TRUE(peer.send_error(CAN_ERR_RESTARTED, {}));
  ASSERT_TRUE(peer.send(0x43, {3}));
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x43U);
  stats = bus.statistics();
  EXPECT_FALSE(stats.bus_off_now);
  EXPECT_FALSE(stats.error_passive);
  EXPECT_EQ(stats.restarts, 1U);
  EXPECT_EQ(stats.faults, 2U);
  EXPECT_EQ(stats.frames_rx, 2U);

  // A bus without error frames saw only the two data frames.
  ASSERT_EQ(quiet.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x42U);
  ASSERT_EQ(quiet.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x43U);
  EXPECT_EQ(quiet.receive(frame, 100ms), ReadStatus::kTimeout);
  EXPECT_EQ(quiet.statistics().error_frames, 0U);
}

TEST_F(SocketCanVm, ReceiveQueueOverflowIsCounted) {
  SocketCanOptions options = vcan_options();
  options.receive_buffer_bytes = 1;  // the kernel rounds up to its minimum: a few frames
  SocketCanBus bus(options);
  ASSERT_EQ(bus.open(), "");
  PeerSocket peer;
  constexpr int kBurst = 200;
  for (int i = 0; i < kBurst; ++i) ASSERT_TRUE(peer.send(0x55, {static_cast<std::uint8_t>(i)}));
  hal::CanFrame frame;
  while (bus.receive(frame, 0ms) == ReadStatus::kOk) {
  }
  const std::uint64_t kept = bus.statistics().frames_rx;
  EXPECT_GT(kept, 0U);
  EXPECT_LT(kept, static_cast<std::uint64_t>(kBurst));
  // The drop count rides on the next queued frame.
  ASSERT_TRUE(peer.send(0x56, {}));
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x56U);
  EXPECT_EQ(bus.statistics().rx_dropped + kept, static_cast<std::uint64_t>(kBurst));
  std::printf("burst of %d: %llu delivered, %llu dropped by the kernel\n", kBurst,
              static_cast<unsigned long long>(kept), static_cast<unsigned long long>(bus.statistics().rx_dropped));
}

TEST_F(SocketCanVm, AFullTransmitQueueIsCountedAndNeverBlocks) {
  RestoreInterface restore;
  // netem holds every frame for 10 s in a queue of 4, like a controller that never gets the
  // bus; further frames are refused with ENOBUFS.
  ASSERT_EQ(vm_test::shell(std::string("tc qdisc add dev ") + kInterface + " root netem delay 10s limit 4"), 0)
      << "tc/netem unavailable";
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  hal::CanFrame out;
  out.id = 0x77;
  out.length = 1;
  int accepted = 0;
  int refused = 0;
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 20; ++i) {
    out.data[0] = static_cast<std::uint8_t>(i);
    const ReadStatus status = bus.send(out);
    ASSERT_TRUE(status == ReadStatus::kOk || status == ReadStatus::kNoData) << hal::to_string(status);
    (status == ReadStatus::kOk ? accepted : refused) += 1;
  }
  const auto elapsed = std::chrono::steady_clock::now() - start;
  EXPECT_EQ(accepted, 4);
  EXPECT_EQ(refused, 16);
  const auto stats = bus.statistics();
  EXPECT_EQ(stats.frames_tx, 4U);
  EXPECT_EQ(stats.tx_dropped, 16U);
  EXPECT_TRUE(bus.is_open());
  EXPECT_LT(elapsed, 5s);  // far less than the 10 s the queue holds frames: nothing blocked
  // Once the queue drains, sending works again.
  ASSERT_EQ(vm_test::shell(std::string("tc qdisc del dev ") + kInterface + " root"), 0);
  EXPECT_EQ(bus.send(out), ReadStatus::kOk);
}

TEST_F(SocketCanVm, InterfaceDownIsAFaultAndTheBusReopensWhenItComesBack) {
  RestoreInterface restore;
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  hal::CanFrame frame;
  ASSERT_EQ(vm_test::shell(std::string("ip link set ") + kInterface + " down"), 0);
  EXPECT_EQ(bus.receive(frame, 500ms), ReadStatus::kFault);
  EXPECT_FALSE(bus.is_open());
  hal::CanFrame out;
  out.id = 0x10;
  EXPECT_EQ(bus.send(out), ReadStatus::kFault);  // still down: the reopen fails
  EXPECT_EQ(bus.receive(frame, 100ms), ReadStatus::kFault);

  ASSERT_TRUE(vcan_up());
  EXPECT_EQ(bus.receive(frame, 100ms), ReadStatus::kTimeout);  // reopened, idle
  EXPECT_TRUE(bus.is_open());
  PeerSocket peer;
  ASSERT_TRUE(peer.send(0x11, {9}));
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x11U);
  EXPECT_EQ(bus.send(out), ReadStatus::kOk);
  const auto stats = bus.statistics();
  EXPECT_EQ(stats.reopens, 1U);
  EXPECT_EQ(stats.faults, 3U);
}

TEST_F(SocketCanVm, InterfaceRemovalIsAFaultAndTheBusReopensOnANewInterface) {
  RestoreInterface restore;
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  hal::CanFrame frame;
  ASSERT_EQ(vm_test::shell(std::string("ip link del ") + kInterface), 0);
  EXPECT_EQ(bus.receive(frame, 500ms), ReadStatus::kFault);
  EXPECT_EQ(bus.receive(frame, 100ms), ReadStatus::kFault);  // no interface to reopen on

  ASSERT_EQ(vm_test::shell(std::string("ip link add dev ") + kInterface + " type vcan"), 0);
  ASSERT_TRUE(vcan_up());
  EXPECT_EQ(bus.receive(frame, 100ms), ReadStatus::kTimeout);
  PeerSocket peer;
  ASSERT_TRUE(peer.send(0x12, {7}));
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  EXPECT_EQ(frame.id, 0x12U);
  EXPECT_EQ(bus.statistics().reopens, 1U);
}

TEST(AllocationCounter, SeesAllocations) {
  test_support::CountAllocations count;
  std::vector<int> values(1000, 1);
  volatile int sink = values[999];
  (void)sink;
  EXPECT_GT(count.allocations(), 0);
}

TEST_F(SocketCanVm, SteadyStateReceiveAndSendAllocateNothing) {
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  PeerSocket peer;
  hal::CanFrame frame;
  hal::CanFrame out;
  out.id = 0x99;
  out.length = 8;
  ASSERT_TRUE(peer.send(0x98, {0}));
  ASSERT_EQ(bus.receive(frame, 2000ms), ReadStatus::kOk);
  ASSERT_EQ(bus.send(out), ReadStatus::kOk);

  constexpr std::size_t kFrames = 50;  // well within the default receive buffer
  for (std::size_t i = 0; i < kFrames; ++i) ASSERT_TRUE(peer.send(0x98, {static_cast<std::uint8_t>(i)}));
  std::array<ReadStatus, kFrames> received{};
  std::array<ReadStatus, kFrames> sent{};
  ReadStatus idle = ReadStatus::kOk;
  long allocations = 0;
  {
    test_support::CountAllocations count;
    for (std::size_t i = 0; i < kFrames; ++i) {
      received[i] = bus.receive(frame, 2000ms);
      sent[i] = bus.send(out);
    }
    idle = bus.receive(frame, 20ms);
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(std::count(received.begin(), received.end(), ReadStatus::kOk), static_cast<long>(kFrames));
  EXPECT_EQ(std::count(sent.begin(), sent.end(), ReadStatus::kOk), static_cast<long>(kFrames));
  EXPECT_EQ(idle, ReadStatus::kTimeout);
}

TEST_F(SocketCanVm, InvalidFramesAreRefusedWithoutClosingTheBus) {
  SocketCanBus bus(vcan_options());
  ASSERT_EQ(bus.open(), "");
  hal::CanFrame out;
  out.id = 0x800;  // 12 bits in a standard frame
  EXPECT_EQ(bus.send(out), ReadStatus::kFault);
  out.id = 0x20000000;
  out.extended = true;  // 30 bits
  EXPECT_EQ(bus.send(out), ReadStatus::kFault);
  out.id = 0x100;
  out.extended = false;
  out.length = 9;
  EXPECT_EQ(bus.send(out), ReadStatus::kFault);
  EXPECT_EQ(bus.statistics().tx_invalid, 3U);
  EXPECT_TRUE(bus.is_open());
  out.length = 8;
  EXPECT_EQ(bus.send(out), ReadStatus::kOk);
}

}  // namespace
}  // namespace rankslam::socketcan
