#pragma once

#include "rankslam/hal/interfaces.hpp"
#include "rankslam/hal/messages.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <thread>

namespace rankslam::hal {

/// What a NearestImage did with a camera's images.
struct NearestImageCounters {
  std::uint64_t read = 0;      ///< Images taken from the camera.
  std::uint64_t paired = 0;    ///< Images handed out with a frame.
  std::uint64_t unpaired = 0;  ///< Images passed over: no frame was near enough, or another image was nearer.
  std::uint64_t faults = 0;    ///< Reads that returned kFault.
};

/// Pairs a second camera's images with another stream's frames by nearest stamp, online. For
/// each frame, in stamp order, the camera is read up to its first image after the frame, and of
/// the last kHeld images the one nearest the frame is handed out if it is within the gap and was
/// not handed out before. A live camera is read instead by a thread of its own (start_reader()),
/// which keeps the newest kHeld images, so its driver never runs out of buffers however slow the
/// frames come. The images are copies in buffers allocated at set-up; nothing allocates per frame.
class NearestImage {
 public:
  /// Images kept for pairing: the newest ones read.
  static constexpr std::size_t kHeld = 4;

  /// `max_gap_ns`: largest stamp difference of a pair.
  NearestImage(Camera& camera, std::int64_t max_gap_ns) : camera_(camera), max_gap_ns_(max_gap_ns) {}
  ~NearestImage() { stop_reader(); }
  NearestImage(const NearestImage&) = delete;
  NearestImage& operator=(const NearestImage&) = delete;

  /// Allocates the buffers for the camera's images (`type`: CV_8UC3 or CV_8UC1).
  void allocate(int width, int height, int type);
  /// Reads the camera on a thread from now on, each read waiting at most `wait`.
  void start_reader(std::chrono::milliseconds wait);
  /// Stops and joins the reader; safe to call twice.
  void stop_reader();

  /// The image nearest `stamp_ns`, or nullptr. Without a reader thread the camera is read here,
  /// each read waiting at most `wait` (a lossless replay waits for its images). The image stays
  /// valid until the next call.
  [[nodiscard]] const ImageFrame* take(std::int64_t stamp_ns, std::chrono::milliseconds wait);

  /// The camera's stream has ended (a recording's last image was read).
  [[nodiscard]] bool ended() const;
  /// What the camera's last read returned (kOk before any).
  [[nodiscard]] ReadStatus last_status() const;
  [[nodiscard]] NearestImageCounters counters() const;

 private:
  struct Held {
    ImageFrame frame;
    bool valid = false;
    bool taken = false;
  };

  /// One read of the camera into the ring; false when it brought no image. Takes the lock itself.
  bool read_one(std::chrono::milliseconds wait);

  Camera& camera_;
  std::int64_t max_gap_ns_;
  mutable std::mutex mutex_;
  // Ring of the newest images read; newest_ indexes the latest.
  std::array<Held, kHeld> held_;
  std::size_t newest_ = kHeld - 1;
  // With a reader: the image handed out, copied so that the reader may overwrite its slot.
  ImageFrame handed_;
  ImageFrame incoming_;
  bool ended_ = false;
  ReadStatus last_status_ = ReadStatus::kOk;
  NearestImageCounters counters_;
  std::atomic<bool> stop_{false};
  std::thread reader_;
};

}  // namespace rankslam::hal
