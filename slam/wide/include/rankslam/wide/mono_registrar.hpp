#pragma once

#include "rankslam/robust/bearing.hpp"
#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/workspace.hpp"
#include "rankslam/wide/features.hpp"

#include <Eigen/Geometry>
#include <opencv2/features2d.hpp>

#include <vector>

namespace rankslam::wide {

/// How an RGB-D frame is registered to a wide-angle frame.
struct MonoRegistrationOptions {
  /// Lowe's ratio test: the best match's descriptor distance below this share of the second's.
  float ratio = 0.8F;
  /// Keep only matches that are each other's best in both directions.
  bool mutual = true;
  /// Fewest MSSE inliers a registration must have (tracking's `min_inliers`).
  int min_inliers = 12;
  /// Largest standard deviation of the registration's translation (MonoRegistration::
  /// position_sigma_m) it may have, metres: three of them stay within 10 cm.
  double max_position_sigma_m = 0.03;
  /// Most matches the estimator takes; sized at set-up.
  int max_matches = 4000;
  robust::MsseConfig msse;
};

/// One RGB-D-to-wide-angle registration.
struct MonoRegistration {
  bool ok = false;
  /// Maps points of the RGB-D (colour) camera's frame into the wide-angle camera's frame.
  Eigen::Isometry3d T_wide_rgbd = Eigen::Isometry3d::Identity();
  int matches = 0;
  int inliers = 0;
  /// MSSE's scale of the inliers' chord residuals (≈ radians).
  double scale = 0.0;
  /// Standard deviation of the translation of T_wide_rgbd along its least certain direction,
  /// metres, from the inliers' geometry and MSSE's scale: what a few distant, clustered inliers
  /// leave loose.
  double position_sigma_m = 0.0;
  /// Information of T_wide_rgbd over ξ = (translation, rotation) for T_wide_rgbd ← exp(ξ)·T_wide_rgbd:
  /// the inliers' Gauss-Newton information over MSSE's scale squared.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
};

/// RGB-D-to-wide-angle registration (ALGORITHMS.md §6.4): SIFT matches between an RGB-D frame's
/// points and a wide-angle frame's features, then P3P hypotheses and MSSE (§1) on the rays in the
/// original wide-angle frame; MSSE's segmentation grows the inlier set.
class MonoRegistrar {
 public:
  explicit MonoRegistrar(const MonoRegistrationOptions& options = {});

  [[nodiscard]] MonoRegistration register_frames(const RgbdFeatures& rgbd, const WideFeatures& wide);

 private:
  MonoRegistrationOptions options_;
  cv::BFMatcher matcher_;
  robust::BearingModel model_;
  robust::RobustWorkspace workspace_;
  std::vector<std::vector<cv::DMatch>> forward_;
  std::vector<cv::DMatch> backward_;
  Eigen::Matrix3Xd points_;
  Eigen::Matrix3Xd rays_;
};

}  // namespace rankslam::wide
