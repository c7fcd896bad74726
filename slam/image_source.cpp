#include "rankslam/slam/image_source.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>

namespace rankslam::slam {

double mean_brightness(const cv::Mat& gray) {
  if (gray.empty()) return 0.0;
  return cv::mean(gray)[0];
}

InfraredFilter::InfraredFilter(int width, int height)
    : width_(width),
      height_(height),
      element_(cv::getStructuringElement(cv::MORPH_RECT, cv::Size(3, 3))),
      lut_(1, 256, CV_8UC1),
      ir8_(height, width, CV_8UC1),
      opened_(height, width, CV_8UC1),
      median_(height, width, CV_8UC1) {
  for (int v = 0; v < 256; ++v) lut_.at<unsigned char>(0, v) = static_cast<unsigned char>(std::min(255, (3 * v + 1) / 2));
}

void InfraredFilter::brighten(const cv::Mat& in, cv::Mat& out) const { cv::LUT(in, lut_, out); }

bool InfraredFilter::apply(const cv::Mat& ir, cv::Mat& out) {
  if (ir.cols != width_ || ir.rows != height_) return false;
  const cv::Mat* source = &ir;
  if (ir.type() == CV_16UC1) {
    ir.convertTo(ir8_, CV_8U, 1.0 / 4.0);
    source = &ir8_;
  } else if (ir.type() != CV_8UC1) {
    return false;
  }
  // Replicated borders: the default border of morphology would brighten or darken the edge rows.
  cv::morphologyEx(*source, opened_, cv::MORPH_OPEN, element_, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  cv::medianBlur(opened_, median_, 5);
  brighten(median_, out);
  return true;
}

}  // namespace rankslam::slam
