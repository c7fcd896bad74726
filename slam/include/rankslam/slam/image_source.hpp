#pragma once

#include <opencv2/core/mat.hpp>

#include <array>
#include <cstdint>
#include <string_view>

namespace rankslam::slam {

/// The image a frame's features were detected on.
enum class ImageSource : std::uint8_t {
  kColour,    ///< The grey colour image.
  kInfrared,  ///< The pre-processed IR image (dark scenes, docs/methods.md §2).
};

[[nodiscard]] constexpr std::string_view to_string(ImageSource source) {
  switch (source) {
    case ImageSource::kColour: return "colour";
    case ImageSource::kInfrared: return "infrared";
  }
  return "unknown";
}

/// Mean grey level of an 8-bit single-channel image, 0..255; 0 for an empty image.
[[nodiscard]] double mean_brightness(const cv::Mat& gray);

/// IR pre-processing of the thesis (ch. 3): a 3×3 morphological opening (erosion, then dilation)
/// removes the projector's speckle dots, which are smaller than the element; a 5×5 median
/// smooths what is left of them and the sensor noise; brightness is raised by 50 % so that FAST
/// finds corners in the dim image. Output buffers are allocated at construction.
class InfraredFilter {
 public:
  InfraredFilter(int width, int height);

  /// `ir` is CV_8UC1, or CV_16UC1 with 10-bit values (the Kinect's IR stream through OpenNI2),
  /// which is reduced to 8 bits first. Returns false, leaving `out` untouched, for any other
  /// type or a size other than the one set up.
  [[nodiscard]] bool apply(const cv::Mat& ir, cv::Mat& out);

  /// The brightness step alone: out = min(255, round(1.5·in)), halves rounded up; exact in
  /// integers.
  void brighten(const cv::Mat& in, cv::Mat& out) const;

 private:
  int width_;
  int height_;
  cv::Mat element_;
  cv::Mat lut_;
  cv::Mat ir8_;
  cv::Mat opened_;
  cv::Mat median_;
};

}  // namespace rankslam::slam
