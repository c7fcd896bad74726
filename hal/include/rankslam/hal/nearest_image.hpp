#pragma once

#include "rankslam/hal/interfaces.hpp"
#include "rankslam/hal/messages.hpp"

#include <array>
#include <chrono>
#include <cstdint>

namespace rankslam::hal {

/// What a NearestImage did with a camera's images.
struct NearestImageCounters {
  std::uint64_t read = 0;      ///< Images taken from the camera.
  std::uint64_t paired = 0;    ///< Images handed out with a frame.
  std::uint64_t unpaired = 0;  ///< Images passed over: no frame was near enough, or another image was nearer.
  std::uint64_t faults = 0;    ///< Reads that returned kFault.
};

/// Pairs a second camera's images with another stream's frames by nearest stamp, online: for
/// each frame, in stamp order, the camera is read up to its first image after the frame, and
/// the nearer of the two images around the frame is handed out if it is within the gap and
/// was not handed out before. Both images are copies in two buffers allocated at set-up, so
/// the camera's own buffers are free again at once; nothing allocates per frame.
class NearestImage {
 public:
  /// `max_gap_ns`: largest stamp difference of a pair.
  NearestImage(Camera& camera, std::int64_t max_gap_ns) : camera_(camera), max_gap_ns_(max_gap_ns) {}

  /// Allocates the buffers for the camera's images (`type`: CV_8UC3 or CV_8UC1).
  void allocate(int width, int height, int type);
  /// The image nearest `stamp_ns`, or nullptr. Each read of the camera waits at most `wait`: a
  /// lossless replay waits for its images, a live camera is asked only for what has arrived.
  /// The image stays valid until the next call.
  [[nodiscard]] const ImageFrame* take(std::int64_t stamp_ns, std::chrono::milliseconds wait);

  /// The camera's stream has ended (a recording's last image was read).
  [[nodiscard]] bool ended() const { return ended_; }
  /// What the camera's last read returned (kOk before any).
  [[nodiscard]] ReadStatus last_status() const { return last_status_; }
  [[nodiscard]] const NearestImageCounters& counters() const { return counters_; }

 private:
  struct Held {
    ImageFrame frame;
    bool valid = false;
    bool taken = false;
  };

  Camera& camera_;
  std::int64_t max_gap_ns_;
  // The last image at or before the latest frame, and the image after it.
  Held behind_;
  Held ahead_;
  ImageFrame incoming_;
  bool ended_ = false;
  ReadStatus last_status_ = ReadStatus::kOk;
  NearestImageCounters counters_;
};

}  // namespace rankslam::hal
