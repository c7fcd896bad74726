#pragma once

// One front door to the 2D features rankslam can use: ROS2D (with SIFT descriptors on the
// equalised image, §7.5), OpenCV's SIFT and OpenCV's ORB.

#include "rankslam/features/ros2d.hpp"

#include <opencv2/core/mat.hpp>
#include <opencv2/features2d.hpp>

#include <optional>
#include <string_view>
#include <vector>

namespace rankslam::features {

enum class FeatureKind { ros2d, sift, orb };

/// "ros2d", "sift" or "orb"; nullopt otherwise.
[[nodiscard]] std::optional<FeatureKind> parse_feature_kind(std::string_view name);
[[nodiscard]] std::string_view feature_kind_name(FeatureKind kind);

struct ExtractorOptions {
  FeatureKind kind = FeatureKind::ros2d;
  Ros2dOptions ros2d;
  /// Most features kept (strongest first); 0 keeps all for ROS2D and SIFT. ORB needs a number:
  /// 0 means its own 500. Range ≥ 0.
  int max_features = 0;
  /// SIFT's contrast threshold (OpenCV's default 0.04).
  double sift_contrast_threshold = 0.04;

  [[nodiscard]] std::string_view validate() const;
};

/// Keypoints and descriptors of one image. Descriptors: CV_32F × 128 (ROS2D, SIFT; compare with
/// cv::NORM_L2) or CV_8U × 32 (ORB; cv::NORM_HAMMING).
class FeatureExtractor {
 public:
  explicit FeatureExtractor(const ExtractorOptions& options = {});

  [[nodiscard]] FeatureKind kind() const { return options_.kind; }
  [[nodiscard]] int norm_type() const;

  /// Set-up: sizes ROS2D's workspaces (no-op for the OpenCV detectors).
  void reserve(cv::Size size);
  /// Set-up: ROS2D shares its row loops with `team` (OpenCV's detectors use OpenCV's own pool).
  void use_team(parallel::ThreadTeam* team) { ros2d_.use_team(team); }

  /// `image`: CV_8UC1 or CV_8UC3 (BGR). Keypoints as cv::KeyPoint in full-resolution pixels. False
  /// (both outputs empty) for an empty image or another type.
  bool extract(const cv::Mat& image, std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors);
  /// Keypoints alone, no descriptors.
  bool detect(const cv::Mat& image, std::vector<cv::KeyPoint>& keypoints);

 private:
  bool grey_of(const cv::Mat& image);
  ExtractorOptions options_;
  Ros2dDetector ros2d_;
  cv::Ptr<cv::Feature2D> sift_;
  cv::Ptr<cv::Feature2D> orb_;
  cv::Mat grey_;       // the image being worked on: the caller's grey image or converted_
  cv::Mat converted_;  // grey of a BGR input
};

}  // namespace rankslam::features
