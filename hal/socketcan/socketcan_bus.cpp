#include "rankslam/socketcan/socketcan_bus.hpp"

#include "rankslam/socketcan/error_frame.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <utility>

namespace rankslam::socketcan {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;

std::int64_t clock_ns(clockid_t clock) {
  timespec now{};
  clock_gettime(clock, &now);
  return static_cast<std::int64_t>(now.tv_sec) * kNsPerS + now.tv_nsec;
}

std::int64_t monotonic_ns() { return clock_ns(CLOCK_MONOTONIC); }

// A CLOCK_REALTIME stamp on CLOCK_MONOTONIC, through the clocks' present offset.
std::int64_t realtime_to_monotonic_ns(std::int64_t realtime_ns) {
  const std::int64_t monotonic_before = monotonic_ns();
  const std::int64_t realtime_now = clock_ns(CLOCK_REALTIME);
  const std::int64_t monotonic_after = monotonic_ns();
  const std::int64_t monotonic_now = monotonic_before + (monotonic_after - monotonic_before) / 2;
  return realtime_ns - (realtime_now - monotonic_now);
}

std::string errno_text(int error) { return std::strerror(error); }

// Errors that mean the interface went down or away: the socket must be reopened.
bool is_link_error(int error) {
  return error == ENETDOWN || error == ENODEV || error == ENXIO || error == ENETUNREACH;
}

bool valid_frame(const hal::CanFrame& frame) {
  const std::uint32_t limit = frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
  return frame.id <= limit && frame.length <= CAN_MAX_DLEN;
}

}  // namespace

SocketCanBus::SocketCanBus(SocketCanOptions options) : options_(std::move(options)) {}

SocketCanBus::~SocketCanBus() { close(); }

std::string SocketCanBus::open() {
  close();
  if (options_.interface_name.empty() || options_.interface_name.size() >= IFNAMSIZ) {
    return "socketcan: interface name '" + options_.interface_name + "' must have 1 to " +
           std::to_string(IFNAMSIZ - 1) + " characters";
  }
  if (options_.filters.size() > kMaxFilters) {
    return "socketcan: " + std::to_string(options_.filters.size()) + " filters given, at most " +
           std::to_string(kMaxFilters) + " supported";
  }
  for (const auto& filter : options_.filters) {
    const std::uint32_t limit = filter.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
    if (filter.id > limit || filter.mask > limit) {
      return "socketcan: filter id/mask " + std::to_string(filter.id) + "/" + std::to_string(filter.mask) +
             " exceeds the " + (filter.extended ? "29" : "11") + "-bit identifier range";
    }
  }
  if (options_.receive_buffer_bytes < 0) return "socketcan: receive_buffer_bytes must not be negative";
  statistics_ = {};
  if (auto error = open_socket(); !error.empty()) return error;
  opened_ = true;
  return {};
}

std::string SocketCanBus::open_socket() {
  const std::string& name = options_.interface_name;
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    const int error = errno;
    if (error == EAFNOSUPPORT || error == EPROTONOSUPPORT) {
      return "socketcan: this kernel has no CAN raw sockets (" + errno_text(error) +
             "); load the can and can-raw modules";
    }
    return "socketcan: socket(PF_CAN, SOCK_RAW, CAN_RAW) failed: " + errno_text(error);
  }
  const auto fail = [&](const std::string& what) {
    const int error = errno;
    ::close(fd);
    return "socketcan: " + name + ": " + what + (error != 0 ? ": " + errno_text(error) : std::string());
  };

  ifreq request{};
  std::memcpy(request.ifr_name, name.c_str(), name.size() + 1);
  if (::ioctl(fd, SIOCGIFINDEX, &request) < 0) return fail("no such interface");
  const int index = request.ifr_ifindex;
  if (::ioctl(fd, SIOCGIFFLAGS, &request) < 0) return fail("cannot read the interface flags");
  if ((request.ifr_flags & IFF_UP) == 0) {
    errno = 0;
    return fail("the interface is down (ip link set " + name + " up)");
  }

  // Data frames only: the RTR bit is part of every mask, so remote frames never match.
  std::array<can_filter, kMaxFilters> filters{};
  std::size_t filter_count = 0;
  if (options_.filters.empty()) {
    filters[0] = {.can_id = 0, .can_mask = CAN_RTR_FLAG};
    filter_count = 1;
  } else {
    for (const auto& filter : options_.filters) {
      filters[filter_count++] = {
          .can_id = filter.id | (filter.extended ? CAN_EFF_FLAG : 0U),
          .can_mask = filter.mask | CAN_EFF_FLAG | CAN_RTR_FLAG,
      };
    }
  }
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                   static_cast<socklen_t>(filter_count * sizeof(can_filter))) < 0) {
    return fail("setsockopt(CAN_RAW_FILTER)");
  }
  const can_err_mask_t error_mask = options_.error_frames ? CAN_ERR_MASK : 0U;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &error_mask, sizeof(error_mask)) < 0) {
    return fail("setsockopt(CAN_RAW_ERR_FILTER)");
  }
  const int on = 1;
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof(on)) < 0) return fail("setsockopt(SO_TIMESTAMPNS)");
  if (::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof(on)) < 0) return fail("setsockopt(SO_RXQ_OVFL)");
  if (options_.receive_buffer_bytes > 0 &&
      ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &options_.receive_buffer_bytes, sizeof(int)) < 0) {
    return fail("setsockopt(SO_RCVBUF)");
  }

  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = index;
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&address), sizeof(address)) < 0) return fail("bind");
  fd_ = fd;
  return {};
}

void SocketCanBus::close_socket() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void SocketCanBus::close() {
  close_socket();
  opened_ = false;
}

bool SocketCanBus::ensure_open() {
  if (fd_ >= 0) return true;
  if (!opened_) return false;
  const std::int64_t now = monotonic_ns();
  const std::int64_t interval_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(options_.reopen_interval).count();
  if (last_reopen_attempt_ns_ != 0 && now - last_reopen_attempt_ns_ < interval_ns) return false;
  last_reopen_attempt_ns_ = now;
  if (!open_socket().empty()) return false;
  ++statistics_.reopens;
  return true;
}

hal::ReadStatus SocketCanBus::fault() {
  ++statistics_.faults;
  return hal::ReadStatus::kFault;
}

hal::ReadStatus SocketCanBus::receive(hal::CanFrame& frame, std::chrono::milliseconds wait) {
  if (!ensure_open()) return fault();
  const std::int64_t wait_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::max(wait, std::chrono::milliseconds{0})).count();
  const std::int64_t deadline_ns = monotonic_ns() + wait_ns;

  can_frame raw{};
  iovec io{.iov_base = &raw, .iov_len = sizeof(raw)};
  alignas(cmsghdr) std::array<char, CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t))> control{};
  for (;;) {
    msghdr message{};
    message.msg_iov = &io;
    message.msg_iovlen = 1;
    message.msg_control = control.data();
    message.msg_controllen = control.size();
    const ssize_t received = ::recvmsg(fd_, &message, MSG_DONTWAIT);
    if (received < 0) {
      const int error = errno;
      if (error == EINTR) continue;
      if (error != EAGAIN && error != EWOULDBLOCK) {
        // ENETDOWN, ENODEV and anything unexpected: the socket is no longer usable.
        close_socket();
        return fault();
      }
      const std::int64_t remaining_ns = deadline_ns - monotonic_ns();
      if (remaining_ns <= 0) {
        if (statistics_.bus_off_now) return fault();
        return wait_ns == 0 ? hal::ReadStatus::kNoData : hal::ReadStatus::kTimeout;
      }
      pollfd request{.fd = fd_, .events = POLLIN, .revents = 0};
      const timespec timeout{.tv_sec = remaining_ns / kNsPerS, .tv_nsec = remaining_ns % kNsPerS};
      const int ready = ::ppoll(&request, 1, &timeout, nullptr);
      if (ready < 0 && errno != EINTR) {
        close_socket();
        return fault();
      }
      // On readiness, an error (POLLERR) included, recvmsg() tells what happened.
      continue;
    }
    if (static_cast<std::size_t>(received) < sizeof(can_frame)) continue;  // not a classic frame

    std::int64_t stamp_ns = 0;
    for (cmsghdr* header = CMSG_FIRSTHDR(&message); header != nullptr; header = CMSG_NXTHDR(&message, header)) {
      if (header->cmsg_level != SOL_SOCKET) continue;
      if (header->cmsg_type == SCM_TIMESTAMPNS) {
        timespec stamp{};
        std::memcpy(&stamp, CMSG_DATA(header), sizeof(stamp));
        stamp_ns = realtime_to_monotonic_ns(static_cast<std::int64_t>(stamp.tv_sec) * kNsPerS + stamp.tv_nsec);
      } else if (header->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t dropped = 0;
        std::memcpy(&dropped, CMSG_DATA(header), sizeof(dropped));
        statistics_.rx_dropped = dropped;  // the socket's running total
      }
    }
    if (stamp_ns == 0) stamp_ns = monotonic_ns();

    std::array<std::uint8_t, 8> data{};
    std::memcpy(data.data(), raw.data, data.size());
    if ((raw.can_id & CAN_ERR_FLAG) != 0) {
      const ErrorFrameEffect effect = apply_error_frame(raw.can_id, data, statistics_);
      if (effect.bus_off) return fault();
      continue;
    }
    if ((raw.can_id & CAN_RTR_FLAG) != 0) continue;

    frame.stamp_ns = stamp_ns;
    frame.extended = (raw.can_id & CAN_EFF_FLAG) != 0;
    frame.id = raw.can_id & (frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    frame.length = std::min<std::uint8_t>(raw.len, CAN_MAX_DLEN);
    frame.data = data;
    ++statistics_.frames_rx;
    return hal::ReadStatus::kOk;
  }
}

hal::ReadStatus SocketCanBus::send(const hal::CanFrame& frame) {
  if (!valid_frame(frame)) {
    ++statistics_.tx_invalid;
    return fault();
  }
  if (!ensure_open()) return fault();
  can_frame raw{};
  raw.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0U);
  raw.len = frame.length;
  std::memcpy(raw.data, frame.data.data(), frame.length);
  for (;;) {
    const ssize_t sent = ::send(fd_, &raw, sizeof(raw), MSG_DONTWAIT);
    if (sent == static_cast<ssize_t>(sizeof(raw))) {
      ++statistics_.frames_tx;
      return hal::ReadStatus::kOk;
    }
    const int error = sent < 0 ? errno : EIO;
    if (error == EINTR) continue;
    if (error == ENOBUFS || error == EAGAIN || error == EWOULDBLOCK) {
      ++statistics_.tx_dropped;
      return hal::ReadStatus::kNoData;
    }
    if (is_link_error(error)) close_socket();
    return fault();
  }
}

}  // namespace rankslam::socketcan
