#pragma once

// Synthetic RGB-D frames of a textured wall for the SLAM loop tests.
#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cstdint>
#include <random>

namespace rankslam::slam {

inline constexpr double kFx = 500.0;
inline constexpr double kPlaneDepth_m = 2.0;

inline hal::Calibration pinhole() {
  hal::Calibration calibration;
  calibration.rgb.fx = calibration.rgb.fy = kFx;
  calibration.rgb.cx = 319.5;
  calibration.rgb.cy = 239.5;
  return calibration;
}

// A textured wall 2 m in front of the camera: moving the camera sideways by s pixels' worth
// (s·z/f metres) shifts the view of the texture by s pixels.
class WallSequence {
 public:
  WallSequence() : texture_(480 + 200, 640 + 400, CV_8UC3) {
    std::mt19937 rng(3);
    cv::Mat noise(texture_.rows / 4, texture_.cols / 4, CV_8UC3);
    cv::randu(noise, cv::Scalar::all(0), cv::Scalar::all(255));
    cv::resize(noise, texture_, texture_.size(), 0, 0, cv::INTER_CUBIC);
    cv::GaussianBlur(texture_, texture_, cv::Size(3, 3), 0.8);
  }

  hal::RgbdFrame frame(int shift_px, std::uint32_t sequence) {
    hal::RgbdFrame frame;
    frame.sequence = sequence;
    frame.stamp_s = sequence / 30.0;
    frame.rgb = texture_(cv::Rect(200 + shift_px, 100, 640, 480)).clone();
    frame.depth = cv::Mat(480, 640, CV_16UC1, cv::Scalar(kPlaneDepth_m * 5000.0));
    return frame;
  }

  // The same view with the lights off: a colour image of a few grey levels, and the IR image
  // (registered to it) showing the texture.
  hal::RgbdFrame dark_frame(int shift_px, std::uint32_t sequence) {
    hal::RgbdFrame frame = this->frame(shift_px, sequence);
    cv::cvtColor(frame.rgb, frame.ir, cv::COLOR_BGR2GRAY);
    frame.rgb.convertTo(frame.rgb, CV_8U, 0.04);
    return frame;
  }

  static double metres(int shift_px) { return shift_px * kPlaneDepth_m / kFx; }

 private:
  cv::Mat texture_;
};

}  // namespace rankslam::slam
