#pragma once

// Stereo rectification: maps built once at set-up (cv::stereoRectify + initUndistortRectifyMap),
// then one remap per image. Already rectified input (KITTI) passes through.

#include <opencv2/core/mat.hpp>

#include "rankslam/stereo/dataset.hpp"

namespace rankslam::stereo {

/// The rectified rig: both cameras share K, the right one sits `baseline_m` along +x of the left,
/// so a point (X, Y, Z) of the left camera is seen at u_l = fx·X/Z + cx, u_r = u_l − fx·b/Z, same v.
struct RectifiedRig {
  cv::Size size;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
  double baseline_m = 0.0;
};

class Rectifier {
 public:
  /// Set-up (allocates, may throw cv::Exception on an impossible calibration, which the caller
  /// catches): the rectification maps, or nothing for rectified input.
  explicit Rectifier(const StereoCalibration& calibration);

  [[nodiscard]] const RectifiedRig& rig() const { return rig_; }
  /// Rotation from the raw left camera into the rectified left camera (identity for KITTI): poses
  /// of the rectified frame are turned back into the raw left camera's with it.
  [[nodiscard]] const Eigen::Matrix3d& R_rect_left() const { return R_rect_left_; }

  /// Grey CV_8UC1 images in, rectified out (buffers reused when the size repeats). False on an
  /// empty image or one of another size than the calibration's.
  bool rectify(const cv::Mat& left, const cv::Mat& right, cv::Mat& left_rect, cv::Mat& right_rect) const;

 private:
  RectifiedRig rig_;
  Eigen::Matrix3d R_rect_left_ = Eigen::Matrix3d::Identity();
  bool pass_through_ = false;
  cv::Size raw_size_;
  cv::Mat map_left_x_, map_left_y_, map_right_x_, map_right_y_;
};

}  // namespace rankslam::stereo
