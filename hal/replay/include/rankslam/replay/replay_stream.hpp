#pragma once

#include "rankslam/hal/status.hpp"

#include <array>
#include <chrono>
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

/// How a replay camera paces a recording.
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

/// The reader thread and slot pool every replay camera shares: a thread decodes a recording's
/// frames, in order, into a fixed pool of slots the camera allocated; the consumer takes them
/// oldest first. A frame that fails to decode is counted, named in a warning and skipped. A
/// camera derives from it, owns the slots and calls stop() in its destructor, before they go.
class ReplayStream {
 public:
  /// Slots in the decode pool: one being read by the consumer, the rest decoded ahead.
  static constexpr std::size_t kPoolSlots = 4;
  static_assert(kPoolSlots >= 2, "the consumer holds one slot while the reader fills another");

  ReplayStream(const ReplayStream&) = delete;
  ReplayStream& operator=(const ReplayStream&) = delete;

  [[nodiscard]] ReplayCounters counters() const;
  /// Warnings since the last call (one per skipped frame, naming the file), moved out.
  [[nodiscard]] std::vector<std::string> take_warnings();

 protected:
  explicit ReplayStream(ReplayOptions options) : options_(options) {}
  ~ReplayStream();

  /// Checks the options and starts the reader on frames 0 .. frame_count - 1; empty on success.
  [[nodiscard]] std::string start(std::uint32_t frame_count);
  /// Stops and joins the reader; safe to call twice.
  void stop();
  /// The next decoded slot, oldest first, into `slot`: kOk, kTimeout after `wait`, or
  /// kEndOfStream. The slot stays the consumer's until the next call.
  [[nodiscard]] hal::ReadStatus next(std::size_t& slot, std::chrono::milliseconds wait);
  /// Adds a warning that does not skip a frame (e.g. a missing optional image).
  void warn(std::string warning);

  [[nodiscard]] const ReplayOptions& options() const { return options_; }

 private:
  /// Decodes frame `index` into slot `slot`; an empty string on success, else what went wrong.
  [[nodiscard]] virtual std::string decode_into(std::uint32_t index, std::size_t slot) = 0;
  /// Frame `index`'s recorded stamp, for pacing.
  [[nodiscard]] virtual double stamp_s(std::uint32_t index) const = 0;
  /// Names frame `index` in a warning (number and file).
  [[nodiscard]] virtual std::string describe(std::uint32_t index) const = 0;

  void reader_loop();
  /// The reader thread's work, from frame `index` on; `index` tells how far it got.
  void read_frames(std::uint32_t& index);

  ReplayOptions options_;
  std::uint32_t frame_count_ = 0;
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
