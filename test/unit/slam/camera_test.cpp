#include "rankslam/camera/depth_camera.hpp"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>

namespace rankslam::slam {
namespace {

hal::CameraCalibration fr1() {
  hal::CameraCalibration camera;
  camera.fx = 517.3;
  camera.fy = 516.5;
  camera.cx = 318.6;
  camera.cy = 255.3;
  camera.distortion = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
  return camera;
}

TEST(DepthCameraModel, PinholeWithoutDistortionIsTheTextbookFormula) {
  hal::CameraCalibration camera = fr1();
  camera.distortion = {};
  const camera::DepthCameraModel model(camera, 5000.0);
  const Eigen::Vector3f p = model.back_project(100, 400, 2.0F);
  EXPECT_NEAR(p.x(), (100 - 318.6) * 2.0 / 517.3, 1e-5);
  EXPECT_NEAR(p.y(), (400 - 255.3) * 2.0 / 516.5, 1e-5);
  EXPECT_FLOAT_EQ(p.z(), 2.0F);
  EXPECT_FLOAT_EQ(model.metres(10000), 2.0F);
}

TEST(DepthCameraModel, RaysReprojectOntoTheirDistortedPixels) {
  const hal::CameraCalibration camera = fr1();
  const camera::DepthCameraModel model(camera, 5000.0);
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  const cv::Vec<double, 5> d(camera.distortion[0], camera.distortion[1], camera.distortion[2], camera.distortion[3],
                             camera.distortion[4]);
  for (const auto& [u, v] : std::vector<std::pair<int, int>>{{0, 0}, {639, 479}, {320, 240}, {50, 400}, {600, 30}}) {
    const Eigen::Vector2f ray = model.ray(u, v);
    std::vector<cv::Point3d> object{{ray.x(), ray.y(), 1.0}};
    std::vector<cv::Point2d> image;
    cv::projectPoints(object, cv::Vec3d::zeros(), cv::Vec3d::zeros(), K, d, image);
    EXPECT_NEAR(image[0].x, u, 0.05) << u << "," << v;
    EXPECT_NEAR(image[0].y, v, 0.05) << u << "," << v;
  }
}

}  // namespace
}  // namespace rankslam::slam
