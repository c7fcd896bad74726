#include "rankslam/v4l2/frame_conversion.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <limits>

namespace rankslam::v4l2 {

bool yuyv_to_bgr(const std::uint8_t* data, std::size_t bytes_used, int width, int height,
                 std::size_t bytes_per_line, cv::Mat& bgr) {
  if (data == nullptr || width <= 0 || height <= 0 || width % 2 != 0) return false;
  const auto row_bytes = static_cast<std::size_t>(width) * 2;
  if (bytes_per_line < row_bytes) return false;
  if (bytes_used < bytes_per_line * static_cast<std::size_t>(height - 1) + row_bytes) return false;
  try {
    // A view of the driver's buffer, no copy; cvtColor writes into bgr's existing memory.
    const cv::Mat packed(height, width, CV_8UC2, const_cast<std::uint8_t*>(data), bytes_per_line);
    cv::cvtColor(packed, bgr, cv::COLOR_YUV2BGR_YUYV);
  } catch (const cv::Exception&) {
    return false;
  }
  return true;
}

bool mjpeg_to_bgr(const std::uint8_t* data, std::size_t bytes_used, int width, int height, cv::Mat& bgr) {
  // OpenCV leaves the destination untouched, and says nothing, when no decoder recognises the
  // data, so anything not starting like a JPEG is refused here.
  if (data == nullptr || bytes_used < 4 || data[0] != 0xFF || data[1] != 0xD8) return false;
  if (bytes_used > static_cast<std::size_t>(std::numeric_limits<int>::max())) return false;
  // A frame cut short on the wire still decodes (libjpeg pads it with grey), so it must end
  // with the end-of-image marker; cameras may pad the payload with zeros after it.
  std::size_t end = bytes_used;
  while (end > 2 && data[end - 1] == 0) --end;
  if (data[end - 2] != 0xFF || data[end - 1] != 0xD9) return false;
  bool ok = false;
  try {
    // Decoded into a fresh image, then copied: given a destination, imdecode() leaves it
    // untouched and still returns it when the header cannot be read, so failure would look
    // like success. The decoder allocates per frame anyway.
    const cv::Mat encoded(1, static_cast<int>(bytes_used), CV_8UC1, const_cast<std::uint8_t*>(data));
    const cv::Mat decoded = cv::imdecode(encoded, cv::IMREAD_COLOR);
    ok = !decoded.empty() && decoded.cols == width && decoded.rows == height && decoded.type() == CV_8UC3;
    if (ok) decoded.copyTo(bgr);
  } catch (const cv::Exception&) {
    ok = false;
  }
  // A failed or odd-sized decode may have released or resized bgr; keep the promised shape.
  if (!ok) bgr.create(height, width, CV_8UC3);
  return ok;
}

}  // namespace rankslam::v4l2
