#pragma once

#include <opencv2/core/mat.hpp>

#include <array>
#include <cstdint>

namespace rankslam::hal {

/// One registered colour + depth (+ optional IR) capture. Images are views into a driver-owned
/// pool slot: valid until the frame is handed back, never reallocated per frame.
struct RgbdFrame {
  /// Index in the stream (recording line or device frame number).
  std::uint32_t sequence = 0;
  /// Capture time on the monotonic clock (replay: recording stamp), nanoseconds.
  std::int64_t stamp_ns = 0;
  /// Capture time as the recording states it (seconds since the epoch for TUM recordings).
  double stamp_s = 0.0;
  cv::Mat rgb;    ///< CV_8UC3, BGR. Empty when the colour stream is off.
  cv::Mat depth;  ///< CV_16UC1, raw units (Calibration::depth_scale per metre); 0 = no data.
  cv::Mat ir;     ///< CV_8UC1 or CV_16UC1 infrared, registered to depth; may be empty.
};

/// One wide-angle camera capture.
struct ImageFrame {
  std::uint32_t sequence = 0;
  std::int64_t stamp_ns = 0;
  double stamp_s = 0.0;
  cv::Mat image;  ///< CV_8UC3 BGR or CV_8UC1.
};

/// A classic CAN 2.0 frame as it crossed the bus.
struct CanFrame {
  std::int64_t stamp_ns = 0;
  std::uint32_t id = 0;  ///< 11-bit or 29-bit identifier, without flag bits.
  bool extended = false;
  std::uint8_t length = 0;
  std::array<std::uint8_t, 8> data{};
};

}  // namespace rankslam::hal
