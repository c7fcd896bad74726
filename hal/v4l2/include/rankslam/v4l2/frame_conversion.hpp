#pragma once

#include "rankslam/core/fourcc.hpp"

#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <cstdint>
#include <string>

namespace rankslam::v4l2 {

/// Converts one packed YUYV 4:2:2 image (Y0 U Y1 V per pixel pair, rows `bytes_per_line`
/// apart) to BGR in `bgr`, which is reused when it already is width x height CV_8UC3. False,
/// with `bgr` untouched, when `bytes_used` is too small for the image.
[[nodiscard]] bool yuyv_to_bgr(const std::uint8_t* data, std::size_t bytes_used, int width, int height,
                               std::size_t bytes_per_line, cv::Mat& bgr);

/// Decodes one MJPEG frame (a JPEG image) into `bgr`, reused when it already is width x height
/// CV_8UC3. False when the data is no JPEG, is cut short (no end-of-image marker), is corrupt,
/// or decodes to another size; `bgr` then keeps its size and type (its content is unspecified).
[[nodiscard]] bool mjpeg_to_bgr(const std::uint8_t* data, std::size_t bytes_used, int width, int height,
                                cv::Mat& bgr);

}  // namespace rankslam::v4l2
