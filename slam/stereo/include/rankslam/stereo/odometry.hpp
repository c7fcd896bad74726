#pragma once

// Stereo visual odometry (docs/methods.md §16): features on both rectified images, left-right
// matching and triangulation, matching of the current left features to the previous frame's 3D
// points, P3P hypotheses ranked and segmented by MSSE, a robust reprojection refinement, pose
// concatenation, and an optional sliding-window bundle adjustment over the last stereo pairs.

#include <cstdint>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "rankslam/features/extractor.hpp"
#include "rankslam/robust/bearing.hpp"
#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/rigid.hpp"
#include "rankslam/robust/workspace.hpp"
#include "rankslam/stereo/rectifier.hpp"
#include "rankslam/stereo/stereo_matcher.hpp"
#include "rankslam/stereo/window_ba.hpp"

namespace rankslam::stereo {

/// How the frame-to-frame motion is hypothesised.
enum class MotionModel {
  p3p,    ///< previous 3D points against current left bearings (robust::BearingModel)
  rigid,  ///< previous 3D points against current triangulated points (robust::RigidModel)
};

struct StereoOdometryConfig {
  /// Feature kind and its options; max_features is overridden by `max_features` below. ROS2D
  /// keeps the thesis' every-point second group: on the EuRoC head, local peaks only gave 2.6 mm
  /// ATE against 1.1 mm (docs/results.md §12).
  features::ExtractorOptions features;
  /// Most features per image (strongest first), the same cap for every kind. Range [50, 20000].
  int max_features = 2000;
  StereoMatcherConfig stereo;
  /// Lowe's ratio of the frame-to-frame descriptor matching (mutual as well). Range (0, 1].
  double temporal_ratio = 0.8;
  MotionModel motion = MotionModel::p3p;
  /// MSSE over the P3P (or rigid) hypotheses; κ 0.1 as the rigid registration (docs/methods.md §1).
  robust::MsseConfig msse;
  /// Fewer MSSE inliers than this: the frame is not tracked and keeps the previous pose. Range [6, 1000].
  int min_inliers = 15;
  /// Robust reprojection refinement of the MSSE pose on its inliers.
  bool refine = true;
  /// Sliding-window bundle adjustment (the `--no-ba` switch turns it off).
  bool bundle_adjustment = true;
  /// Stereo pairs in the window, the oldest one fixed (thesis: 10). Range [2, 64].
  int window_size = 10;
  WindowBaConfig ba;

  /// Empty when every field is in range, else the name of the first offending field.
  [[nodiscard]] std::string_view validate() const;
};

/// What one stereo pair gave.
struct StereoFrameResult {
  bool tracked = false;  ///< false for the first frame and for frames that kept the previous pose
  /// The rectified left camera in the world (the rectified left camera of the first frame).
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  int left_features = 0;
  int right_features = 0;
  int stereo_points = 0;
  int temporal_matches = 0;
  int inliers = 0;
  double features_ms = 0.0;  ///< extraction on both images
  double matching_ms = 0.0;  ///< stereo and temporal matching
  double pose_ms = 0.0;      ///< MSSE and refinement
  double ba_ms = 0.0;        ///< window bundle adjustment
  double total_ms = 0.0;
};

class StereoOdometry {
 public:
  /// Set-up (allocates): extractor, matcher, window and landmark table. The config must validate.
  StereoOdometry(const RectifiedRig& rig, const StereoOdometryConfig& config);

  /// One rectified grey stereo pair (CV_8UC1, the rig's size). Returns the pose of its left camera.
  StereoFrameResult process(const cv::Mat& left, const cv::Mat& right);

  [[nodiscard]] const StereoOdometryConfig& config() const { return config_; }
  [[nodiscard]] const RectifiedRig& rig() const { return rig_; }

 private:
  /// The features of one frame that later frames match against.
  struct FrameFeatures {
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    std::vector<int> right_of_left;
    std::vector<Eigen::Vector3d> points;     ///< own triangulation, rectified left camera (NaN: none)
    std::vector<std::int64_t> landmark_of;   ///< −1: none
  };

  bool estimate_motion(Eigen::Isometry3d& T_cur_prev, StereoFrameResult& result);
  void add_observations(const Eigen::Isometry3d& T_world_cur);

  RectifiedRig rig_;
  StereoOdometryConfig config_;
  features::FeatureExtractor extractor_;
  StereoMatcher stereo_matcher_;
  robust::BearingModel bearing_model_;
  robust::RigidModel rigid_model_;
  robust::RobustWorkspace workspace_;
  LandmarkStore landmarks_;

  FrameFeatures previous_;
  FrameFeatures current_;
  std::vector<cv::KeyPoint> right_keypoints_;
  cv::Mat right_descriptors_;
  bool has_previous_ = false;

  // Temporal correspondences of the current frame (capacity max_features).
  cv::Mat reference_descriptors_;
  std::vector<int> reference_index_;  // row of reference_descriptors_ → feature of previous_
  std::vector<int> match_of_current_;
  std::vector<int> matched_current_;  // correspondence k: current feature
  std::vector<int> matched_previous_; // correspondence k: previous feature
  Eigen::Matrix3Xd reference_points_;
  Eigen::Matrix3Xd matched_points_;   // correspondence k: the previous frame's point
  Eigen::Matrix3Xd current_bearings_;
  Eigen::Matrix3Xd current_points_;
  std::vector<std::uint8_t> inlier_;  // per correspondence
  std::vector<Eigen::Vector3d> refine_points_;
  std::vector<Observation> refine_observations_;

  std::vector<WindowFrame> window_;   // ring of window_size frames
  std::vector<WindowFrame*> window_order_;
  int window_count_ = 0;
  int window_head_ = 0;               // slot of the newest frame
  std::int64_t frame_index_ = 0;
  Eigen::Isometry3d T_world_previous_ = Eigen::Isometry3d::Identity();
};

}  // namespace rankslam::stereo
