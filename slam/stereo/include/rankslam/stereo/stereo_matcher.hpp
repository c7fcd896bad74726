#pragma once

// Left-right matching of one rectified stereo pair along epipolar rows, and the triangulation of
// the matches into the left camera. Nothing allocates per pair once reserve() has run for the
// feature counts seen.

#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include "rankslam/stereo/rectifier.hpp"

namespace rankslam::stereo {

struct StereoMatcherConfig {
  /// Largest |v_l − v_r| of a match [px]: rectification leaves a residual row error.
  double max_row_difference_px = 2.0;
  /// Disparities accepted: (0, max] [px]; 0 < d keeps points in front of the rig.
  double max_disparity_px = 160.0;
  /// Lowe's ratio: best distance < ratio × second best among the candidates of the row band.
  double ratio = 0.8;
  /// Keep a match only when the left feature is also the right feature's best candidate.
  bool mutual = true;
};

/// Descriptor distance of row i of a and row j of b: L2 for CV_32F descriptors, Hamming for CV_8U.
[[nodiscard]] float descriptor_distance(const cv::Mat& a, int i, const cv::Mat& b, int j);

class StereoMatcher {
 public:
  StereoMatcher(const RectifiedRig& rig, const StereoMatcherConfig& config);

  /// Set-up: room for up to max_keypoints per image.
  void reserve(int max_keypoints);

  /// For each left keypoint: right_of_left[i] = matched right keypoint or −1, and points_left[i]
  /// its triangulated point in the rectified left camera (NaN without a match). Returns the count.
  int match(const std::vector<cv::KeyPoint>& left, const cv::Mat& left_descriptors,
            const std::vector<cv::KeyPoint>& right, const cv::Mat& right_descriptors,
            std::vector<int>& right_of_left, std::vector<Eigen::Vector3d>& points_left);

 private:
  RectifiedRig rig_;
  StereoMatcherConfig config_;
  std::vector<int> right_order_;      // right keypoints by ascending v
  std::vector<float> right_rows_;     // their v, for the row-band search
  std::vector<float> right_best_;     // per right keypoint: least distance to any left candidate
  std::vector<int> right_best_left_;  // and which left keypoint it was
};

/// Mutual nearest neighbours with Lowe's ratio test between two descriptor sets (query → train).
/// match_of_query[i] = train index or −1. Brute force through cv::BFMatcher (SIMD); its k-NN
/// lists are allocated per call.
int match_descriptors(const cv::Mat& query, const cv::Mat& train, double ratio, std::vector<int>& match_of_query);

}  // namespace rankslam::stereo
