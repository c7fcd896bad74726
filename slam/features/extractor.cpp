#include "rankslam/features/extractor.hpp"

#include <opencv2/imgproc.hpp>

#include <stdexcept>
#include <string>

namespace rankslam::features {

std::optional<FeatureKind> parse_feature_kind(std::string_view name) {
  if (name == "ros2d") return FeatureKind::ros2d;
  if (name == "sift") return FeatureKind::sift;
  if (name == "orb") return FeatureKind::orb;
  return std::nullopt;
}

std::string_view feature_kind_name(FeatureKind kind) {
  switch (kind) {
    case FeatureKind::ros2d: return "ros2d";
    case FeatureKind::sift: return "sift";
    case FeatureKind::orb: return "orb";
  }
  return "?";
}

std::string_view ExtractorOptions::validate() const {
  if (max_features < 0) return "max_features";
  if (!(sift_contrast_threshold > 0.0 && sift_contrast_threshold < 1.0)) return "sift_contrast_threshold";
  if (kind == FeatureKind::ros2d) {
    if (const auto field = ros2d.validate(); !field.empty()) return field;
  }
  return {};
}

namespace {

Ros2dOptions ros2d_options(const ExtractorOptions& options) {
  Ros2dOptions o = options.ros2d;
  if (options.max_features > 0) o.max_features = options.max_features;
  return o;
}

}  // namespace

FeatureExtractor::FeatureExtractor(const ExtractorOptions& options)
    : options_(options), ros2d_(ros2d_options(options)) {
  if (const auto field = options_.validate(); !field.empty()) {
    throw std::invalid_argument("feature options: " + std::string(field) + " out of range");
  }
  // SIFT also describes ROS2D's keypoints (§7.5): its descriptor needs the same octave layers.
  sift_ = cv::SIFT::create(options_.kind == FeatureKind::sift ? options_.max_features : 0,
                           options_.kind == FeatureKind::ros2d ? options_.ros2d.layers : 3,
                           options_.sift_contrast_threshold);
  if (options_.kind == FeatureKind::orb) {
    orb_ = cv::ORB::create(options_.max_features > 0 ? options_.max_features : 500);
  }
}

int FeatureExtractor::norm_type() const {
  return options_.kind == FeatureKind::orb ? cv::NORM_HAMMING : cv::NORM_L2;
}

void FeatureExtractor::reserve(cv::Size size) {
  if (options_.kind == FeatureKind::ros2d) ros2d_.reserve(size);
  converted_.create(size, CV_8UC1);
}

bool FeatureExtractor::grey_of(const cv::Mat& image) {
  if (image.empty()) return false;
  if (image.type() == CV_8UC1) {
    grey_ = image;
    return true;
  }
  if (image.type() == CV_8UC3) {
    // Never into grey_ itself: it may still share an earlier caller's image.
    cv::cvtColor(image, converted_, cv::COLOR_BGR2GRAY);
    grey_ = converted_;
    return true;
  }
  return false;
}

bool FeatureExtractor::detect(const cv::Mat& image, std::vector<cv::KeyPoint>& keypoints) {
  keypoints.clear();
  if (!grey_of(image)) return false;
  switch (options_.kind) {
    case FeatureKind::ros2d: return ros2d_.detect(grey_, keypoints);
    case FeatureKind::sift: sift_->detect(grey_, keypoints); return true;
    case FeatureKind::orb: orb_->detect(grey_, keypoints); return true;
  }
  return false;
}

bool FeatureExtractor::extract(const cv::Mat& image, std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors) {
  keypoints.clear();
  descriptors.release();
  if (!grey_of(image)) return false;
  switch (options_.kind) {
    case FeatureKind::ros2d:
      if (!ros2d_.detect(grey_, keypoints)) return false;
      // SIFT descriptors on the histogram-equalised image (§7.5).
      if (!keypoints.empty()) sift_->compute(ros2d_.equalized(), keypoints, descriptors);
      return true;
    case FeatureKind::sift: sift_->detectAndCompute(grey_, cv::noArray(), keypoints, descriptors); return true;
    case FeatureKind::orb: orb_->detectAndCompute(grey_, cv::noArray(), keypoints, descriptors); return true;
  }
  return false;
}

}  // namespace rankslam::features
