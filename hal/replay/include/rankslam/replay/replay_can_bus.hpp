#pragma once

#include "rankslam/hal/interfaces.hpp"

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace rankslam::replay {

/// How the replay bus paces a recording's CAN frames.
struct ReplayCanOptions {
  /// Identifier of the wheel encoder frames (standard, 11 bit): the frames release_through()
  /// waits for (hal::WheelGeometry::can_id of the recording's calibration).
  std::uint32_t wheel_can_id = hal::WheelGeometry{}.can_id;
};

/// Plays a recording's can.log through the CanBus interface, in stamp order, paced by the camera:
/// release_through(stamp) lets receive() hand out every frame up to the first wheel frame at or
/// after the camera frame's stamp, the moment a live bus would have delivered the wheels' motion
/// up to that frame. Frames sent are accepted and counted, not stored. Never allocates after
/// construction; not thread-safe.
class ReplayCanBus final : public hal::CanBus {
 public:
  /// `frames` (Recording::can_frames) must outlive the bus.
  ReplayCanBus(const std::vector<hal::CanFrame>& frames, ReplayCanOptions options);

  /// Fails when the frames are not in stamp order (open_recording sorts them).
  [[nodiscard]] std::string open() override;
  /// The next released frame (kOk); kNoData until more are released; kEndOfStream once every
  /// frame of the recording has been handed out. Never waits.
  [[nodiscard]] hal::ReadStatus receive(hal::CanFrame& frame, std::chrono::milliseconds wait) override;
  [[nodiscard]] hal::ReadStatus send(const hal::CanFrame& frame) override;
  void close() override;
  [[nodiscard]] hal::CanBusStatistics statistics() const override { return statistics_; }

  /// Releases the frames not yet released up to and including the first wheel frame stamped at
  /// or after `stamp_ns` (all remaining frames when there is none); at least one frame while any
  /// is left.
  void release_through(std::int64_t stamp_ns);

  /// Frames in the recording.
  [[nodiscard]] std::size_t size() const { return frames_.size(); }
  /// Frames released so far (handed out or not).
  [[nodiscard]] std::size_t released() const { return released_; }

 private:
  [[nodiscard]] bool is_wheel_frame(const hal::CanFrame& frame) const {
    return frame.id == options_.wheel_can_id && !frame.extended;
  }

  const std::vector<hal::CanFrame>& frames_;
  ReplayCanOptions options_;
  std::size_t released_ = 0;  ///< frames_[0, released_) may be received
  std::size_t next_ = 0;      ///< the next frame receive() hands out
  bool open_ = false;
  hal::CanBusStatistics statistics_;
};

}  // namespace rankslam::replay
