#include "rankslam/stereo/odometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rankslam/core/stopwatch.hpp"

namespace rankslam::stereo {

std::string_view StereoOdometryConfig::validate() const {
  if (!features.validate().empty()) return "features";
  if (max_features < 50 || max_features > 20000) return "max_features";
  if (!(stereo.max_row_difference_px >= 0.0 && stereo.max_row_difference_px <= 20.0)) return "stereo.max_row_difference_px";
  if (!(stereo.max_disparity_px > 0.0 && stereo.max_disparity_px <= 10000.0)) return "stereo.max_disparity_px";
  if (!(stereo.ratio > 0.0 && stereo.ratio <= 1.0)) return "stereo.ratio";
  if (!(temporal_ratio > 0.0 && temporal_ratio <= 1.0)) return "temporal_ratio";
  if (!msse.validate().empty()) return "msse";
  if (min_inliers < 6 || min_inliers > 1000) return "min_inliers";
  if (window_size < 2 || window_size > 64) return "window_size";
  if (!(ba.huber_px > 0.0 && ba.huber_px <= 100.0)) return "ba.huber_px";
  if (ba.max_iterations < 1 || ba.max_iterations > 1000) return "ba.max_iterations";
  return {};
}

namespace {

features::ExtractorOptions extractor_options(const StereoOdometryConfig& config) {
  features::ExtractorOptions options = config.features;
  options.max_features = config.max_features;
  return options;
}

}  // namespace

StereoOdometry::StereoOdometry(const RectifiedRig& rig, const StereoOdometryConfig& config)
    : rig_(rig),
      config_(config),
      extractor_(extractor_options(config)),
      stereo_matcher_(rig, config.stereo),
      bearing_model_(config.max_features),
      rigid_model_(config.max_features),
      workspace_(config.max_features),
      // A landmark lives while it is tracked; the table turns over after this many new ones.
      landmarks_((config.window_size + 2) * config.max_features * 2) {
  const auto n = static_cast<std::size_t>(config.max_features);
  extractor_.reserve(rig.size);
  stereo_matcher_.reserve(config.max_features);
  for (FrameFeatures* f : {&previous_, &current_}) {
    f->keypoints.reserve(n);
    f->right_of_left.reserve(n);
    f->points.reserve(n);
    f->landmark_of.reserve(n);
  }
  right_keypoints_.reserve(n);
  reference_index_.reserve(n);
  match_of_current_.reserve(n);
  matched_current_.reserve(n);
  matched_previous_.reserve(n);
  reference_points_.resize(3, config.max_features);
  matched_points_.resize(3, config.max_features);
  current_bearings_.resize(3, config.max_features);
  current_points_.resize(3, config.max_features);
  inlier_.reserve(n);
  refine_points_.reserve(n);
  refine_observations_.reserve(n);
  window_.resize(static_cast<std::size_t>(config.window_size));
  for (auto& frame : window_) frame.observations.reserve(n);
  window_order_.reserve(window_.size());
}

bool StereoOdometry::estimate_motion(Eigen::Isometry3d& T_cur_prev, StereoFrameResult& result) {
  // The previous frame's 3D points: with the window, its landmarks as the adjustment left them;
  // without, its own stereo triangulation (plain frame-to-frame odometry).
  const Eigen::Isometry3d T_prev_world = T_world_previous_.inverse();
  const int cols = previous_.descriptors.cols;
  if (reference_descriptors_.cols != cols || reference_descriptors_.type() != previous_.descriptors.type()) {
    reference_descriptors_.create(config_.max_features, cols, previous_.descriptors.type());
  }
  reference_index_.clear();
  for (std::size_t k = 0; k < previous_.keypoints.size() && static_cast<int>(reference_index_.size()) < config_.max_features; ++k) {
    Eigen::Vector3d p;
    if (config_.bundle_adjustment) {
      const Landmark* l = landmarks_.find(previous_.landmark_of[k]);
      if (l == nullptr) continue;
      p = T_prev_world * l->p_world;
    } else {
      if (previous_.right_of_left[k] < 0) continue;
      p = previous_.points[k];
    }
    const int row = static_cast<int>(reference_index_.size());
    previous_.descriptors.row(static_cast<int>(k)).copyTo(reference_descriptors_.row(row));
    reference_points_.col(row) = p;
    reference_index_.push_back(static_cast<int>(k));
  }
  const int references = static_cast<int>(reference_index_.size());
  match_descriptors(current_.descriptors, reference_descriptors_.rowRange(0, references), config_.temporal_ratio,
                    match_of_current_);

  const auto pose_start = SteadyClock::now();
  struct PoseTimer {  // the pose stage ends at every return
    StereoFrameResult& result;
    SteadyClock::time_point since;
    ~PoseTimer() { result.pose_ms = elapsed_ms(since); }
  } pose_timer{result, pose_start};
  matched_current_.clear();
  matched_previous_.clear();
  int n = 0;
  for (std::size_t i = 0; i < match_of_current_.size(); ++i) {
    const int row = match_of_current_[i];
    if (row < 0) continue;
    // The rigid model needs the current point in 3D too.
    if (config_.motion == MotionModel::rigid && current_.right_of_left[i] < 0) continue;
    const cv::Point2f pt = current_.keypoints[i].pt;
    current_bearings_.col(n) =
        Eigen::Vector3d((static_cast<double>(pt.x) - rig_.cx) / rig_.fx, (static_cast<double>(pt.y) - rig_.cy) / rig_.fy, 1.0)
            .normalized();
    current_points_.col(n) = current_.points[i];
    matched_points_.col(n) = reference_points_.col(row);
    matched_current_.push_back(static_cast<int>(i));
    matched_previous_.push_back(reference_index_[static_cast<std::size_t>(row)]);
    ++n;
  }
  result.temporal_matches = n;
  if (n < std::max(config_.min_inliers, 6)) return false;

  robust::RobustStatus status = robust::RobustStatus::kInvalidInput;
  std::span<const std::uint8_t> mask;
  int inliers = 0;
  if (config_.motion == MotionModel::p3p) {
    status = bearing_model_.set_correspondences(matched_points_.leftCols(n), current_bearings_.leftCols(n));
    if (status != robust::RobustStatus::kOk) return false;
    const auto estimate = robust::estimate_msse(bearing_model_, config_.msse, workspace_);
    if (!estimate.ok()) return false;
    T_cur_prev = estimate.model;
    mask = estimate.inlier_mask;
    inliers = estimate.inlier_count;
  } else {
    status = rigid_model_.set_correspondences(matched_points_.leftCols(n), current_points_.leftCols(n));
    if (status != robust::RobustStatus::kOk) return false;
    const auto estimate = robust::estimate_msse(rigid_model_, config_.msse, workspace_);
    if (!estimate.ok()) return false;
    T_cur_prev = estimate.model;
    mask = estimate.inlier_mask;
    inliers = estimate.inlier_count;
  }
  inlier_.assign(mask.begin(), mask.end());
  result.inliers = inliers;
  if (inliers < config_.min_inliers) return false;

  if (config_.refine) {
    refine_points_.clear();
    refine_observations_.clear();
    for (int k = 0; k < n; ++k) {
      if (!inlier_[static_cast<std::size_t>(k)]) continue;
      const auto i = static_cast<std::size_t>(matched_current_[static_cast<std::size_t>(k)]);
      const int j = current_.right_of_left[i];
      refine_points_.push_back(matched_points_.col(k));
      refine_observations_.push_back({-1, current_.keypoints[i].pt.x, current_.keypoints[i].pt.y,
                                      j >= 0 ? right_keypoints_[static_cast<std::size_t>(j)].pt.x
                                             : std::numeric_limits<float>::quiet_NaN()});
    }
    Eigen::Isometry3d refined = T_cur_prev;
    if (refine_pose(rig_, refine_points_, refine_observations_, config_.ba, refined)) T_cur_prev = refined;
  }
  return true;
}

void StereoOdometry::add_observations(const Eigen::Isometry3d& T_world_cur) {
  window_head_ = (window_head_ + 1) % static_cast<int>(window_.size());
  window_count_ = std::min(window_count_ + 1, static_cast<int>(window_.size()));
  WindowFrame& frame = window_[static_cast<std::size_t>(window_head_)];
  frame.T_world_cam = T_world_cur;
  frame.observations.clear();
  const std::size_t count = current_.keypoints.size();
  current_.landmark_of.assign(count, -1);
  for (std::size_t i = 0; i < count; ++i) {
    std::int64_t id = -1;
    if (const int k = match_of_current_[i]; k >= 0) {
      id = previous_.landmark_of[static_cast<std::size_t>(k)];
      if (landmarks_.find(id) == nullptr) id = -1;
    }
    const int j = current_.right_of_left[i];
    if (id < 0 && j >= 0) id = landmarks_.create(T_world_cur * current_.points[i]);
    if (id < 0) continue;
    current_.landmark_of[i] = id;
    frame.observations.push_back({id, current_.keypoints[i].pt.x, current_.keypoints[i].pt.y,
                                  j >= 0 ? right_keypoints_[static_cast<std::size_t>(j)].pt.x
                                         : std::numeric_limits<float>::quiet_NaN()});
  }
}

StereoFrameResult StereoOdometry::process(const cv::Mat& left, const cv::Mat& right) {
  StereoFrameResult result;
  const auto start = SteadyClock::now();
  extractor_.extract(left, current_.keypoints, current_.descriptors);
  extractor_.extract(right, right_keypoints_, right_descriptors_);
  // The extractor may add orientation duplicates beyond the cap; the tables are sized for the cap.
  const auto cap = static_cast<std::size_t>(config_.max_features);
  if (current_.keypoints.size() > cap) {
    current_.keypoints.resize(cap);
    current_.descriptors = current_.descriptors.rowRange(0, config_.max_features);
  }
  if (right_keypoints_.size() > cap) {
    right_keypoints_.resize(cap);
    right_descriptors_ = right_descriptors_.rowRange(0, config_.max_features);
  }
  result.left_features = static_cast<int>(current_.keypoints.size());
  result.right_features = static_cast<int>(right_keypoints_.size());
  result.features_ms = elapsed_ms(start);

  auto stage = SteadyClock::now();
  result.stereo_points = stereo_matcher_.match(current_.keypoints, current_.descriptors, right_keypoints_,
                                               right_descriptors_, current_.right_of_left, current_.points);
  Eigen::Isometry3d T_world_cur = T_world_previous_;
  match_of_current_.assign(current_.keypoints.size(), -1);
  if (has_previous_) {
    Eigen::Isometry3d T_cur_prev = Eigen::Isometry3d::Identity();
    result.tracked = estimate_motion(T_cur_prev, result);
    if (result.tracked) {
      T_world_cur = T_world_previous_ * T_cur_prev.inverse();
      // Only inlier correspondences carry a landmark into this frame.
      std::fill(match_of_current_.begin(), match_of_current_.end(), -1);
      for (std::size_t k = 0; k < matched_current_.size(); ++k) {
        if (inlier_[k]) match_of_current_[static_cast<std::size_t>(matched_current_[k])] = matched_previous_[k];
      }
    } else {
      std::fill(match_of_current_.begin(), match_of_current_.end(), -1);
    }
  }
  result.matching_ms = elapsed_ms(stage) - result.pose_ms;  // stereo and temporal matching
  add_observations(T_world_cur);

  if (config_.bundle_adjustment && window_count_ >= 2) {
    stage = SteadyClock::now();
    window_order_.clear();
    const int size = static_cast<int>(window_.size());
    for (int k = 0; k < window_count_; ++k) {
      window_order_.push_back(&window_[static_cast<std::size_t>((window_head_ - window_count_ + 1 + k + size) % size)]);
    }
    (void)adjust_window(rig_, window_order_, landmarks_, config_.ba, frame_index_);
    T_world_cur = window_[static_cast<std::size_t>(window_head_)].T_world_cam;
    result.ba_ms = elapsed_ms(stage);
  }

  result.T_world_cam = T_world_cur;
  T_world_previous_ = T_world_cur;
  std::swap(previous_, current_);
  has_previous_ = true;
  ++frame_index_;
  result.total_ms = elapsed_ms(start);
  return result;
}

}  // namespace rankslam::stereo
