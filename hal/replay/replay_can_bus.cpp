#include "rankslam/replay/replay_can_bus.hpp"

#include <algorithm>

namespace rankslam::replay {

ReplayCanBus::ReplayCanBus(const std::vector<hal::CanFrame>& frames, ReplayCanOptions options)
    : frames_(frames), options_(options) {}

std::string ReplayCanBus::open() {
  const auto unordered = std::adjacent_find(frames_.begin(), frames_.end(), [](const hal::CanFrame& a, const hal::CanFrame& b) {
    return b.stamp_ns < a.stamp_ns;
  });
  if (unordered != frames_.end()) {
    return "replay CAN bus: frame " + std::to_string(unordered - frames_.begin() + 1) + " is newer than the one after it";
  }
  released_ = 0;
  next_ = 0;
  statistics_ = {};
  open_ = true;
  return {};
}

hal::ReadStatus ReplayCanBus::receive(hal::CanFrame& frame, std::chrono::milliseconds /*wait*/) {
  if (!open_) {
    ++statistics_.faults;
    return hal::ReadStatus::kFault;
  }
  if (next_ == frames_.size()) return hal::ReadStatus::kEndOfStream;
  if (next_ == released_) return hal::ReadStatus::kNoData;
  frame = frames_[next_++];
  ++statistics_.frames_rx;
  return hal::ReadStatus::kOk;
}

hal::ReadStatus ReplayCanBus::send(const hal::CanFrame& /*frame*/) {
  if (!open_) {
    ++statistics_.faults;
    return hal::ReadStatus::kFault;
  }
  ++statistics_.frames_tx;
  return hal::ReadStatus::kOk;
}

void ReplayCanBus::close() { open_ = false; }

void ReplayCanBus::release_through(std::int64_t stamp_ns) {
  // From the first frame not yet released on, always at least one: the pacing `replay` has
  // always had, so its results stay as they were.
  while (released_ < frames_.size()) {
    const hal::CanFrame& frame = frames_[released_++];
    if (frame.stamp_ns >= stamp_ns && is_wheel_frame(frame)) break;
  }
}

}  // namespace rankslam::replay
