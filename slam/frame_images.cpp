#include "rankslam/slam/frame_images.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace rankslam::slam {
namespace {

// The colour image must brighten to this multiple of the switch threshold before features
// return to it: a scene hovering at the threshold would otherwise flip image kinds every few
// frames, and each switch costs a second feature extraction.
constexpr double kColourReturnFactor = 1.25;

bool valid_image(const cv::Mat& image, int type, int width, int height) {
  return image.type() == type && image.cols == width && image.rows == height;
}

}  // namespace

FrameImages::FrameImages(int width, int height, double ir_switch_brightness)
    : width_(width), height_(height), ir_switch_brightness_(ir_switch_brightness), infrared_filter_(width, height) {
  gray_.create(height_, width_, CV_8UC1);
  infrared_.create(height_, width_, CV_8UC1);
}

void FrameImages::warm_up() {
  cv::cvtColor(cv::Mat(height_, width_, CV_8UC3, cv::Scalar::all(0)), gray_, cv::COLOR_BGR2GRAY);
}

bool FrameImages::has_depth(const hal::RgbdFrame& frame) const {
  return valid_image(frame.depth, CV_16UC1, width_, height_);
}

ImageSource FrameImages::choose_source(const hal::RgbdFrame& frame) {
  gray_valid_ = valid_image(frame.rgb, CV_8UC3, width_, height_);
  if (gray_valid_) cv::cvtColor(frame.rgb, gray_, cv::COLOR_BGR2GRAY);
  infrared_valid_ = false;  // filtered only when needed
  const bool ir_present =
      valid_image(frame.ir, CV_8UC1, width_, height_) || valid_image(frame.ir, CV_16UC1, width_, height_);
  if (!gray_valid_) {
    infrared_active_ = ir_present;
  } else if (!ir_present || ir_switch_brightness_ <= 0.0) {
    infrared_active_ = false;
  } else {
    const double threshold =
        infrared_active_ ? ir_switch_brightness_ * kColourReturnFactor : ir_switch_brightness_;
    infrared_active_ = mean_brightness(gray_) < threshold;
  }
  return infrared_active_ ? ImageSource::kInfrared : ImageSource::kColour;
}

void FrameImages::skip_features(const hal::RgbdFrame& frame) {
  gray_valid_ = valid_image(frame.rgb, CV_8UC3, width_, height_);
  infrared_valid_ = false;
}

const cv::Mat* FrameImages::feature_image(const hal::RgbdFrame& frame, ImageSource source) {
  if (source == ImageSource::kColour) return gray_valid_ ? &gray_ : nullptr;
  if (!infrared_valid_) infrared_valid_ = infrared_filter_.apply(frame.ir, infrared_);
  return infrared_valid_ ? &infrared_ : nullptr;
}

}  // namespace rankslam::slam
