#include "rankslam/wide/features.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace rankslam::wide {

namespace {

void to_grey(const cv::Mat& image, cv::Mat& grey) {
  if (image.channels() == 3) {
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  } else {
    image.copyTo(grey);
  }
}

}  // namespace

WideFeatureExtractor::WideFeatureExtractor(const camera::VirtualViews& views, const SiftOptions& options)
    : views_(views), sift_(cv::SIFT::create(options.features_per_image, 3, options.contrast_threshold)) {
  views_.allocate(rendered_, CV_8UC1);
  const cv::Mat kernel =
      cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * options.border_px + 1, 2 * options.border_px + 1));
  for (int i = 0; i < views_.count(); ++i) {
    cv::Mat mask;
    cv::erode(views_.valid_mask(i), mask, kernel, cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
    masks_.push_back(mask);
  }
}

bool WideFeatureExtractor::extract(const cv::Mat& wide, WideFeatures& out) {
  out.count = 0;
  out.view.clear();
  out.pixel.clear();
  out.descriptors.release();
  to_grey(wide, grey_);
  if (!views_.render(grey_, rendered_)) return false;
  for (int i = 0; i < views_.count(); ++i) {
    sift_->detectAndCompute(rendered_[static_cast<std::size_t>(i)], masks_[static_cast<std::size_t>(i)], keypoints_,
                            descriptors_);
    if (keypoints_.empty()) continue;
    out.descriptors.push_back(descriptors_);
    for (const auto& k : keypoints_) {
      out.view.push_back(i);
      out.pixel.push_back(k.pt);
    }
  }
  out.count = static_cast<int>(out.pixel.size());
  if (out.count == 0) return true;
  out.rays.resize(3, out.count);
  for (int k = 0; k < out.count; ++k) {
    const auto& p = out.pixel[static_cast<std::size_t>(k)];
    out.rays.col(k) = views_.ray(out.view[static_cast<std::size_t>(k)], p.x, p.y);
  }
  return true;
}

RgbdFeatureExtractor::RgbdFeatureExtractor(const camera::DepthCameraModel& camera, const SiftOptions& options)
    : camera_(camera), options_(options), sift_(cv::SIFT::create(options.features_per_image, 3, options.contrast_threshold)) {}

bool RgbdFeatureExtractor::extract(const cv::Mat& image, const cv::Mat& depth, RgbdFeatures& out) {
  out.count = 0;
  out.pixel.clear();
  if (image.cols != camera_.width() || image.rows != camera_.height() || depth.size() != image.size() ||
      depth.type() != CV_16UC1) {
    return false;
  }
  to_grey(image, grey_);
  sift_->detectAndCompute(grey_, cv::noArray(), keypoints_, descriptors_);
  out.points.resize(3, static_cast<Eigen::Index>(keypoints_.size()));
  out.descriptors.create(0, descriptors_.cols, CV_32F);
  for (std::size_t k = 0; k < keypoints_.size(); ++k) {
    const int u = static_cast<int>(std::lround(keypoints_[k].pt.x));
    const int v = static_cast<int>(std::lround(keypoints_[k].pt.y));
    if (u < 0 || v < 0 || u >= camera_.width() || v >= camera_.height()) continue;
    const float z = camera_.metres(depth.at<unsigned short>(v, u));
    if (!(z > 0.0F) || static_cast<double>(z) > options_.max_depth_m) continue;
    const Eigen::Vector2f ray =
        camera_.ray(std::clamp(keypoints_[k].pt.x, 0.0F, static_cast<float>(camera_.width() - 1)),
                    std::clamp(keypoints_[k].pt.y, 0.0F, static_cast<float>(camera_.height() - 1)));
    out.points.col(out.count) = Eigen::Vector3f(ray.x() * z, ray.y() * z, z).cast<double>();
    out.descriptors.push_back(descriptors_.row(static_cast<int>(k)));
    out.pixel.push_back(keypoints_[k].pt);
    ++out.count;
  }
  out.points.conservativeResize(3, out.count);
  return true;
}

}  // namespace rankslam::wide
