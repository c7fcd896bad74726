#pragma once

#include "rankslam/hal/interfaces.hpp"

#include <opencv2/core/mat.hpp>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

namespace rankslam::v4l2 {

/// Pixel formats the camera can stream; both become BGR images.
enum class PixelFormat : std::uint8_t {
  kAuto,   ///< YUYV when the device offers it at the size, otherwise MJPEG.
  kYuyv,   ///< Packed YUV 4:2:2, converted with cv::cvtColor.
  kMjpeg,  ///< Motion JPEG, decoded with cv::imdecode (the decoder allocates per frame).
};

/// Set-up of a V4L2 camera; fixed after construction.
struct V4l2Options {
  /// Video capture device node.
  std::string device = "/dev/video0";
  /// Image size in pixels; the device must offer exactly this size.
  int width = 640;
  int height = 480;
  /// Frame rate requested with VIDIOC_S_PARM, in frames per second; 0 keeps the device's.
  /// The device may choose another rate: negotiated() tells which.
  std::uint32_t fps = 30;
  PixelFormat format = PixelFormat::kAuto;
  /// Memory-mapped capture buffers, 2 .. V4l2Camera::kMaxBuffers. More buffers ride out longer
  /// consumer stalls before the device drops frames.
  std::uint32_t buffer_count = 4;
  /// After a fault, reopen the device on later reads.
  bool reopen_after_fault = true;
  /// The least time between two reopen attempts; 0 = at every read.
  std::chrono::milliseconds reopen_interval{1000};
};

/// What the device agreed to.
struct V4l2Format {
  std::uint32_t pixel_format = 0;    ///< V4L2 four-character code (YUYV or MJPG).
  int width = 0;
  int height = 0;
  std::uint32_t bytes_per_line = 0;  ///< Row pitch of YUYV data.
  std::uint32_t image_bytes = 0;     ///< Largest buffer payload.
  /// Frame interval in seconds as a fraction; 0/0 when the device does not say.
  std::uint32_t interval_numerator = 0;
  std::uint32_t interval_denominator = 0;
  std::uint32_t buffer_count = 0;
  bool monotonic_stamps = false;     ///< The first frame carried V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC.
  std::string driver;                ///< VIDIOC_QUERYCAP driver, card and bus.
  std::string card;
  std::string bus_info;

  [[nodiscard]] double fps() const {
    return interval_numerator == 0 ? 0.0 : static_cast<double>(interval_denominator) / interval_numerator;
  }
};

/// Counters since open().
struct V4l2Counters {
  std::uint64_t frames = 0;     ///< Frames handed to the caller.
  std::uint64_t timeouts = 0;   ///< Reads that ended with kTimeout.
  std::uint64_t dropped = 0;    ///< Frames the device skipped: gaps in v4l2_buffer.sequence.
  std::uint64_t corrupt = 0;    ///< Buffers flagged in error, too short or undecodable.
  std::uint64_t unstamped = 0;  ///< Frames without a monotonic device stamp (stamped at dequeue).
  std::uint64_t faults = 0;     ///< Reads that returned kFault.
  std::uint64_t reopens = 0;    ///< Successful reopens after a fault.
};

/// hal::Camera on a Video4Linux2 capture device with memory-mapped streaming.
///
/// read() waits in poll() at most `wait` (wait 0: kNoData when no frame is ready, longer:
/// kTimeout), converts the oldest captured frame into an image allocated at open() and
/// hands the buffer straight back to the device. frame.image stays valid until the next
/// read() overwrites it. stamp_ns is the device's CLOCK_MONOTONIC capture stamp
/// (v4l2_buffer.timestamp); a device with other stamps is stamped at dequeue and counted.
/// A device that fails or disappears (ENODEV, EIO, POLLERR) makes read() return kFault and
/// closes the device; later reads reopen it when reopen_after_fault is set. Until a reopen
/// succeeds, each read sleeps until an attempt is due or its `wait` ends and returns kFault, so
/// a caller's read loop does not spin.
///
/// One thread at a time.
class V4l2Camera final : public hal::Camera {
 public:
  static constexpr std::size_t kMaxBuffers = 16;
  static constexpr std::size_t kMaxFormats = 128;

  explicit V4l2Camera(V4l2Options options);
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  /// Opens the device, negotiates format and rate, maps the buffers and starts streaming.
  /// Empty on success, otherwise what went wrong.
  [[nodiscard]] std::string open() override;
  [[nodiscard]] hal::ReadStatus read(hal::ImageFrame& frame, std::chrono::milliseconds wait) override;
  void close() override;

  [[nodiscard]] const V4l2Options& options() const { return options_; }
  [[nodiscard]] const V4l2Format& negotiated() const { return format_; }
  [[nodiscard]] const V4l2Counters& counters() const { return counters_; }
  /// One line for the start-up log: device, driver, format, size, rate, buffers.
  [[nodiscard]] std::string describe() const;
  /// True while the device is open and streaming (false after a fault until a reopen).
  [[nodiscard]] bool is_open() const { return fd_ >= 0; }

 private:
  struct Buffer {
    void* data = nullptr;
    std::size_t length = 0;
  };

  std::string open_device();
  void close_device();
  bool ensure_open();
  /// While faulted: sleeps until the next reopen attempt is due or `deadline_ns`, whichever is
  /// first, and makes that attempt. True when the device is open again.
  bool wait_for_reopen(std::int64_t deadline_ns);
  hal::ReadStatus fault();
  /// Converts a dequeued buffer into image_; false when the frame is unusable.
  bool convert(std::uint32_t index, std::uint32_t bytes_used);

  V4l2Options options_;
  V4l2Format format_;
  V4l2Counters counters_;
  int fd_ = -1;
  bool opened_ = false;  // open() succeeded and close() was not called since
  bool streaming_ = false;
  std::int64_t last_reopen_attempt_ns_ = 0;
  std::array<Buffer, kMaxBuffers> buffers_{};
  std::uint32_t mapped_count_ = 0;
  bool have_sequence_ = false;
  std::uint32_t last_sequence_ = 0;
  cv::Mat image_;
};

}  // namespace rankslam::v4l2
