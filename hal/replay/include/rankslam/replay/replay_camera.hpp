#pragma once

#include "rankslam/hal/interfaces.hpp"
#include "rankslam/replay/recording.hpp"

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace rankslam::replay {

/// Slowest and fastest paced replay: a thousandth of the recorded rate to a thousand times it.
inline constexpr double kMinReplayRate = 1e-3;
inline constexpr double kMaxReplayRate = 1e3;

/// How the replay camera paces a recording.
struct ReplayOptions {
  /// 0 = as fast as the consumer takes frames (no frame is ever dropped);
  /// otherwise play at this multiple of the recorded rate (kMinReplayRate .. kMaxReplayRate),
  /// dropping the oldest decoded frame when the consumer falls behind, as a live sensor would.
  double rate = 0.0;
  /// Replay at most this many frames (0 = all).
  std::uint32_t max_frames = 0;
  /// Decode the IR stream when the recording has one.
  bool load_ir = true;
  /// With rate 0: decode the next frames while the consumer works on the current one (the
  /// fastest replay). False: decode a frame only once the consumer has asked for it, so that
  /// decoding never competes with the consumer for the cores, as on the robot, where the driver
  /// delivers decoded images; the consumer's timings are then its own.
  bool decode_ahead = true;
};

/// Counters a replay exposes for the report.
struct ReplayCounters {
  std::uint32_t delivered = 0;  ///< Frames handed to the consumer.
  std::uint32_t corrupt = 0;    ///< Frames skipped because an image was missing or undecodable.
  std::uint32_t dropped = 0;    ///< Frames decoded but overwritten before the consumer took them.
};

/// Plays a recording through the DepthCamera interface. Images are decoded on a reader thread
/// into a fixed pool of slots allocated at open(); a missing or corrupt image skips the frame,
/// counts it and names the file in a warning, never stops the replay. Image files are read only
/// when they are regular files of at most 64 MiB whose header gives the calibration's size.
class ReplayDepthCamera final : public hal::DepthCamera {
 public:
  /// Slots in the decode pool: one being read by the consumer, the rest decoded ahead.
  static constexpr std::size_t kPoolSlots = 4;
  static_assert(kPoolSlots >= 2, "the consumer holds one slot while the reader fills another");

  ReplayDepthCamera(const Recording& recording, ReplayOptions options);
  ~ReplayDepthCamera() override;
  ReplayDepthCamera(const ReplayDepthCamera&) = delete;
  ReplayDepthCamera& operator=(const ReplayDepthCamera&) = delete;

  [[nodiscard]] std::string open() override;
  [[nodiscard]] const hal::Calibration& calibration() const override { return recording_.calibration; }
  /// Hands out the next frame in recording order. The images stay valid until the next read().
  [[nodiscard]] hal::ReadStatus read(hal::RgbdFrame& frame, std::chrono::milliseconds wait) override;
  void close() override;

  /// Frames the replay will deliver at most (after max_frames).
  [[nodiscard]] std::uint32_t frame_count() const { return frame_count_; }
  [[nodiscard]] ReplayCounters counters() const;
  /// Warnings since the last call (one per skipped frame, naming the file), moved out.
  [[nodiscard]] std::vector<std::string> take_warnings();

 private:
  struct Slot {
    hal::RgbdFrame frame;
    std::vector<unsigned char> file_buffer;
  };

  void reader_loop();
  /// The reader thread's work, from frame `index` on; `index` tells how far it got.
  void read_frames(std::uint32_t& index);
  /// Decodes frame `index` into `slot`; an empty string on success, else what went wrong.
  std::string decode_into(std::uint32_t index, Slot& slot);

  const Recording& recording_;
  ReplayOptions options_;
  std::uint32_t frame_count_ = 0;

  std::array<Slot, kPoolSlots> slots_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  // Ring of decoded slot indices waiting for the consumer, oldest first.
  std::array<std::size_t, kPoolSlots> ready_{};
  std::size_t ready_head_ = 0;
  std::size_t ready_count_ = 0;
  std::array<bool, kPoolSlots> slot_free_{};
  std::size_t held_slot_ = kPoolSlots;  // slot the consumer is reading, kPoolSlots = none
  bool reader_done_ = false;
  bool stop_ = false;
  ReplayCounters counters_;
  std::vector<std::string> warnings_;
  std::thread reader_;
};

}  // namespace rankslam::replay
