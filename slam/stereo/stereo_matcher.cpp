#include "rankslam/stereo/stereo_matcher.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include <opencv2/features2d.hpp>

namespace rankslam::stereo {

float descriptor_distance(const cv::Mat& a, int i, const cv::Mat& b, int j) {
  if (a.type() == CV_8U) {
    const auto* pa = a.ptr<std::uint8_t>(i);
    const auto* pb = b.ptr<std::uint8_t>(j);
    int bits = 0;
    int k = 0;
    for (; k + 8 <= a.cols; k += 8) {
      std::uint64_t wa = 0, wb = 0;
      std::memcpy(&wa, pa + k, 8);
      std::memcpy(&wb, pb + k, 8);
      bits += std::popcount(wa ^ wb);
    }
    for (; k < a.cols; ++k) bits += std::popcount(static_cast<unsigned>(pa[k] ^ pb[k]));
    return static_cast<float>(bits);
  }
  const float* pa = a.ptr<float>(i);
  const float* pb = b.ptr<float>(j);
  float sum = 0.0f;
  for (int k = 0; k < a.cols; ++k) {
    const float d = pa[k] - pb[k];
    sum += d * d;
  }
  return std::sqrt(sum);
}

StereoMatcher::StereoMatcher(const RectifiedRig& rig, const StereoMatcherConfig& config) : rig_(rig), config_(config) {}

void StereoMatcher::reserve(int max_keypoints) {
  const auto n = static_cast<std::size_t>(std::max(0, max_keypoints));
  right_order_.reserve(n);
  right_rows_.reserve(n);
  right_best_.reserve(n);
  right_best_left_.reserve(n);
}

int StereoMatcher::match(const std::vector<cv::KeyPoint>& left, const cv::Mat& left_descriptors,
                         const std::vector<cv::KeyPoint>& right, const cv::Mat& right_descriptors,
                         std::vector<int>& right_of_left, std::vector<Eigen::Vector3d>& points_left) {
  const Eigen::Vector3d nan = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  right_of_left.assign(left.size(), -1);
  points_left.assign(left.size(), nan);
  if (left.empty() || right.empty() || left_descriptors.rows != static_cast<int>(left.size()) ||
      right_descriptors.rows != static_cast<int>(right.size()) || left_descriptors.type() != right_descriptors.type() ||
      left_descriptors.cols != right_descriptors.cols) {
    return 0;
  }
  const int n_right = static_cast<int>(right.size());
  right_order_.resize(right.size());
  for (int j = 0; j < n_right; ++j) right_order_[static_cast<std::size_t>(j)] = j;
  std::sort(right_order_.begin(), right_order_.end(),
            [&](int a, int b) { return right[static_cast<std::size_t>(a)].pt.y < right[static_cast<std::size_t>(b)].pt.y; });
  right_rows_.resize(right.size());
  for (std::size_t k = 0; k < right.size(); ++k) right_rows_[k] = right[static_cast<std::size_t>(right_order_[k])].pt.y;
  right_best_.assign(right.size(), std::numeric_limits<float>::infinity());
  right_best_left_.assign(right.size(), -1);

  const auto band = static_cast<float>(config_.max_row_difference_px);
  const auto max_disparity = static_cast<float>(config_.max_disparity_px);
  // Candidate search: per left keypoint the right keypoints within the row band and disparity range.
  std::vector<int>& best_right = right_of_left;  // reused: best right candidate before the tests
  for (std::size_t i = 0; i < left.size(); ++i) {
    const cv::Point2f pl = left[i].pt;
    const auto first = std::lower_bound(right_rows_.begin(), right_rows_.end(), pl.y - band);
    float best = std::numeric_limits<float>::infinity();
    float second = best;
    int best_j = -1;
    for (auto it = first; it != right_rows_.end() && *it <= pl.y + band; ++it) {
      const int j = right_order_[static_cast<std::size_t>(it - right_rows_.begin())];
      const float disparity = pl.x - right[static_cast<std::size_t>(j)].pt.x;
      if (!(disparity > 0.0f && disparity <= max_disparity)) continue;
      const float d = descriptor_distance(left_descriptors, static_cast<int>(i), right_descriptors, j);
      if (d < best) {
        second = best;
        best = d;
        best_j = j;
      } else if (d < second) {
        second = d;
      }
      if (d < right_best_[static_cast<std::size_t>(j)]) {
        right_best_[static_cast<std::size_t>(j)] = d;
        right_best_left_[static_cast<std::size_t>(j)] = static_cast<int>(i);
      }
    }
    // A lone candidate has no second best: the ratio test cannot reject it.
    best_right[i] = (best_j >= 0 && best < static_cast<float>(config_.ratio) * second) ? best_j : -1;
  }
  int count = 0;
  for (std::size_t i = 0; i < left.size(); ++i) {
    const int j = best_right[i];
    if (j < 0) continue;
    if (config_.mutual && right_best_left_[static_cast<std::size_t>(j)] != static_cast<int>(i)) {
      best_right[i] = -1;
      continue;
    }
    const double disparity = static_cast<double>(left[i].pt.x) - static_cast<double>(right[static_cast<std::size_t>(j)].pt.x);
    const double z = rig_.fx * rig_.baseline_m / disparity;
    const double u = left[i].pt.x;
    const double v = 0.5 * (static_cast<double>(left[i].pt.y) + static_cast<double>(right[static_cast<std::size_t>(j)].pt.y));
    points_left[i] = Eigen::Vector3d((u - rig_.cx) * z / rig_.fx, (v - rig_.cy) * z / rig_.fy, z);
    ++count;
  }
  return count;
}

int match_descriptors(const cv::Mat& query, const cv::Mat& train, double ratio, std::vector<int>& match_of_query) {
  match_of_query.assign(static_cast<std::size_t>(query.rows), -1);
  if (query.empty() || train.rows < 2 || query.type() != train.type() || query.cols != train.cols) return 0;
  const int norm = query.type() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2;
  cv::BFMatcher matcher(norm, false);
  std::vector<std::vector<cv::DMatch>> forward;
  matcher.knnMatch(query, train, forward, 2);
  std::vector<std::vector<cv::DMatch>> backward;
  matcher.knnMatch(train, query, backward, 1);
  int count = 0;
  for (const auto& candidates : forward) {
    if (candidates.size() < 2) continue;
    const cv::DMatch& best = candidates[0];
    if (!(best.distance < static_cast<float>(ratio) * candidates[1].distance)) continue;
    const auto& back = backward[static_cast<std::size_t>(best.trainIdx)];
    if (back.empty() || back[0].trainIdx != best.queryIdx) continue;
    match_of_query[static_cast<std::size_t>(best.queryIdx)] = best.trainIdx;
    ++count;
  }
  return count;
}

}  // namespace rankslam::stereo
