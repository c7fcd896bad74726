#include "rankslam/camera/depth_camera.hpp"

#include <opencv2/calib3d.hpp>

namespace rankslam::camera {

DepthCameraModel::DepthCameraModel(const hal::CameraCalibration& calibration, double depth_scale,
                                   double depth_noise_per_m)
    : calibration_(calibration),
      width_(calibration.width),
      height_(calibration.height),
      depth_scale_(depth_scale),
      depth_noise_per_m_(depth_noise_per_m),
      metres_per_unit_(static_cast<float>(1.0 / depth_scale)) {
  const std::size_t count = static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_);
  auto rays = std::make_shared<std::vector<Eigen::Vector2f>>(count);
  std::vector<cv::Point2f> pixels(count);
  for (int v = 0; v < height_; ++v) {
    for (int u = 0; u < width_; ++u) {
      pixels[static_cast<std::size_t>(v * width_ + u)] = cv::Point2f(static_cast<float>(u), static_cast<float>(v));
    }
  }
  const cv::Matx33d K(calibration.fx, 0.0, calibration.cx, 0.0, calibration.fy, calibration.cy, 0.0, 0.0, 1.0);
  std::vector<cv::Point2f> normalised(count);
  if (calibration.model == hal::CameraModel::kFisheye) {
    const cv::Vec4d d(calibration.distortion[0], calibration.distortion[1], calibration.distortion[2],
                      calibration.distortion[3]);
    cv::fisheye::undistortPoints(pixels, normalised, K, d);
  } else {
    const cv::Vec<double, 5> d(calibration.distortion[0], calibration.distortion[1], calibration.distortion[2],
                               calibration.distortion[3], calibration.distortion[4]);
    // Iterative inversion of the distortion, more iterations than the default for the wide
    // corners of fr1's strong radial distortion.
    cv::undistortPoints(pixels, normalised, K, d, cv::noArray(), cv::noArray(),
                        cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 20, 1e-6));
  }
  for (std::size_t i = 0; i < count; ++i) (*rays)[i] = Eigen::Vector2f(normalised[i].x, normalised[i].y);
  ray_data_ = rays->data();
  rays_ = std::move(rays);
}

}  // namespace rankslam::camera
