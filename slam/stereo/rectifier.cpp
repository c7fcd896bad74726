#include "rankslam/stereo/rectifier.hpp"

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

namespace rankslam::stereo {
namespace {

cv::Mat camera_matrix(const CameraIntrinsics& c) {
  return (cv::Mat_<double>(3, 3) << c.fu, 0.0, c.cu, 0.0, c.fv, c.cv, 0.0, 0.0, 1.0);
}

}  // namespace

Rectifier::Rectifier(const StereoCalibration& calibration) : raw_size_(calibration.left.size) {
  if (calibration.rectified) {
    pass_through_ = true;
    rig_.size = calibration.left.size;
    rig_.fx = calibration.left.fu;
    rig_.fy = calibration.left.fv;
    rig_.cx = calibration.left.cu;
    rig_.cy = calibration.left.cv;
    rig_.baseline_m = -calibration.T_right_left.translation().x();
    return;
  }
  const cv::Mat k_left = camera_matrix(calibration.left);
  const cv::Mat k_right = camera_matrix(calibration.right);
  const cv::Mat d_left(calibration.left.radtan, true);
  const cv::Mat d_right(calibration.right.radtan, true);
  cv::Mat rotation(3, 3, CV_64F), translation(3, 1, CV_64F);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) rotation.at<double>(r, c) = calibration.T_right_left.linear()(r, c);
    translation.at<double>(r) = calibration.T_right_left.translation()(r);
  }
  cv::Mat r_left, r_right, p_left, p_right, q;
  // alpha 0: only valid pixels in the rectified images, so no feature sits on the black border.
  cv::stereoRectify(k_left, d_left, k_right, d_right, calibration.left.size, rotation, translation, r_left, r_right,
                    p_left, p_right, q, cv::CALIB_ZERO_DISPARITY, 0.0, calibration.left.size);
  cv::initUndistortRectifyMap(k_left, d_left, r_left, p_left, calibration.left.size, CV_16SC2, map_left_x_, map_left_y_);
  cv::initUndistortRectifyMap(k_right, d_right, r_right, p_right, calibration.left.size, CV_16SC2, map_right_x_,
                              map_right_y_);
  rig_.size = calibration.left.size;
  rig_.fx = p_left.at<double>(0, 0);
  rig_.fy = p_left.at<double>(1, 1);
  rig_.cx = p_left.at<double>(0, 2);
  rig_.cy = p_left.at<double>(1, 2);
  rig_.baseline_m = -p_right.at<double>(0, 3) / p_right.at<double>(0, 0);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) R_rect_left_(r, c) = r_left.at<double>(r, c);
  }
}

bool Rectifier::rectify(const cv::Mat& left, const cv::Mat& right, cv::Mat& left_rect, cv::Mat& right_rect) const {
  if (left.empty() || right.empty() || left.size() != raw_size_ || right.size() != raw_size_ ||
      left.type() != CV_8UC1 || right.type() != CV_8UC1) {
    return false;
  }
  if (pass_through_) {
    left.copyTo(left_rect);
    right.copyTo(right_rect);
    return true;
  }
  cv::remap(left, left_rect, map_left_x_, map_left_y_, cv::INTER_LINEAR);
  cv::remap(right, right_rect, map_right_x_, map_right_y_, cv::INTER_LINEAR);
  return true;
}

}  // namespace rankslam::stereo
