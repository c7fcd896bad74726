#pragma once

#include "rankslam/hal/messages.hpp"
#include "rankslam/socketcan/socketcan_bus.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace rankslam::app {

/// Plays a recording's wheel frames onto the bus on their recorded timing (scaled by `rate`).
class WheelPlayer {
 public:
  WheelPlayer(const std::vector<hal::CanFrame>& frames, const std::string& interface_name, double rate)
      : frames_(frames), rate_(rate > 0.0 ? rate : 1.0) {
    socketcan::SocketCanOptions options;
    options.interface_name = interface_name;
    // This socket only sends: receive nothing but an identifier no one uses.
    options.filters.push_back({0x7FF, 0x7FF, false});
    options.error_frames = false;
    bus_ = std::make_unique<socketcan::SocketCanBus>(options);
  }
  ~WheelPlayer() { stop(); }
  WheelPlayer(const WheelPlayer&) = delete;
  WheelPlayer& operator=(const WheelPlayer&) = delete;

  [[nodiscard]] std::string start() {
    if (auto error = bus_->open(); !error.empty()) return error;
    thread_ = std::thread([this] {
      play();
      finished_ = true;
    });
    return {};
  }
  void stop() {
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    if (thread_.joinable()) thread_.join();
  }
  [[nodiscard]] std::uint64_t sent() const { return sent_.load(); }
  [[nodiscard]] std::uint64_t dropped() const { return dropped_.load(); }
  /// Every frame was sent (or the player stopped).
  [[nodiscard]] bool finished() const { return finished_.load(); }

 private:
  void play() {
    if (frames_.empty()) return;
    const auto start = std::chrono::steady_clock::now();
    const std::int64_t first_ns = frames_.front().stamp_ns;
    for (const hal::CanFrame& frame : frames_) {
      const auto offset = std::chrono::nanoseconds(static_cast<std::int64_t>(static_cast<double>(frame.stamp_ns - first_ns) / rate_));
      {
        std::unique_lock lock(mutex_);
        if (changed_.wait_until(lock, start + offset, [this] { return stop_; })) return;
      }
      if (bus_->send(frame) == hal::ReadStatus::kOk) {
        ++sent_;
      } else {
        ++dropped_;
      }
    }
  }

  const std::vector<hal::CanFrame>& frames_;
  double rate_;
  std::unique_ptr<socketcan::SocketCanBus> bus_;
  std::mutex mutex_;
  std::condition_variable changed_;
  bool stop_ = false;
  std::atomic<std::uint64_t> sent_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<bool> finished_{false};
  std::thread thread_;
};

}  // namespace rankslam::app
