#pragma once

#include "rankslam/hal/messages.hpp"
#include "rankslam/slam/image_source.hpp"

#include <opencv2/core/mat.hpp>

namespace rankslam::slam {

/// The images of the current frame that features and the map read: the colour image in grey,
/// the pre-processed IR image (filtered once, when first asked for), and which of the two the
/// features come from, with hysteresis so a scene near the threshold does not flip kinds.
/// Buffers are allocated at construction.
class FrameImages {
 public:
  /// `ir_switch_brightness`: below this mean grey level the features come from IR (0: never).
  FrameImages(int width, int height, double ir_switch_brightness);

  /// New frame whose features are detected on an image: converts the colour image to grey and
  /// chooses the source, IR when the colour image is dark or absent.
  [[nodiscard]] ImageSource choose_source(const hal::RgbdFrame& frame);
  /// New frame whose features need no image: notes only whether it has colour (for the map).
  void skip_features(const hal::RgbdFrame& frame);
  /// The current frame's feature image of `source`, or null when the frame lacks it.
  [[nodiscard]] const cv::Mat* feature_image(const hal::RgbdFrame& frame, ImageSource source);

  /// The current frame has a colour image of the calibrated size.
  [[nodiscard]] bool has_colour() const { return gray_valid_; }
  /// `frame` has a depth image of the calibrated size.
  [[nodiscard]] bool has_depth(const hal::RgbdFrame& frame) const;
  /// Runs one colour conversion: OpenCV sets up its parallel framework in the first parallel call
  /// of a thread, which would otherwise be the first frame's.
  void warm_up();

 private:
  int width_;
  int height_;
  double ir_switch_brightness_;
  InfraredFilter infrared_filter_;
  cv::Mat gray_;
  bool gray_valid_ = false;
  cv::Mat infrared_;
  bool infrared_valid_ = false;
  bool infrared_active_ = false;
};

}  // namespace rankslam::slam
