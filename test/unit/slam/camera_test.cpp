#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/camera/lens.hpp"
#include "rankslam/camera/virtual_views.hpp"

#include <gtest/gtest.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>
#include <random>

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

/// The simulated corridor's wide-angle camera (a real 190° lens' calibration, rounded).
hal::CameraCalibration wide() {
  hal::CameraCalibration camera;
  camera.model = hal::CameraModel::kFisheye;
  camera.width = 960;
  camera.height = 600;
  camera.fx = 230.0;
  camera.fy = 230.0;
  camera.cx = 479.5;
  camera.cy = 299.5;
  camera.distortion = {0.0129, 0.00266, -0.00587, 0.00126, 0.0};
  return camera;
}

/// A direction `angle` from the optical axis, at azimuth `azimuth`.
Eigen::Vector3d direction(double angle, double azimuth) {
  return {std::sin(angle) * std::cos(azimuth), std::sin(angle) * std::sin(azimuth), std::cos(angle)};
}

TEST(Lens, FisheyeProjectsAsOpenCvInFrontOfTheCamera) {
  const hal::CameraCalibration camera = wide();
  const camera::Lens lens(camera);
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  const cv::Vec4d d(camera.distortion[0], camera.distortion[1], camera.distortion[2], camera.distortion[3]);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> angle(0.0, 1.5);
  std::uniform_real_distribution<double> azimuth(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> range(0.3, 6.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p = range(rng) * direction(angle(rng), azimuth(rng));
    std::vector<cv::Point3d> object{{p.x(), p.y(), p.z()}};
    std::vector<cv::Point2d> image;
    cv::fisheye::projectPoints(object, image, cv::Vec3d::zeros(), cv::Vec3d::zeros(), K, d);
    const auto pixel = lens.project(p);
    ASSERT_TRUE(pixel.has_value());
    EXPECT_NEAR(pixel->x(), image[0].x, 1e-7);
    EXPECT_NEAR(pixel->y(), image[0].y, 1e-7);
  }
}

TEST(Lens, PinholeProjectsAsOpenCv) {
  const hal::CameraCalibration camera = fr1();
  const camera::Lens lens(camera);
  const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
  const cv::Vec<double, 5> d(camera.distortion[0], camera.distortion[1], camera.distortion[2], camera.distortion[3],
                             camera.distortion[4]);
  for (const auto& p : {Eigen::Vector3d(0.0, 0.0, 1.0), Eigen::Vector3d(0.3, -0.2, 1.0),
                        Eigen::Vector3d(-0.6, 0.45, 1.2), Eigen::Vector3d(1.0, 0.7, 2.5)}) {
    std::vector<cv::Point3d> object{{p.x(), p.y(), p.z()}};
    std::vector<cv::Point2d> image;
    cv::projectPoints(object, cv::Vec3d::zeros(), cv::Vec3d::zeros(), K, d, image);
    const auto pixel = lens.project(p);
    ASSERT_TRUE(pixel.has_value());
    EXPECT_NEAR(pixel->x(), image[0].x, 1e-7);
    EXPECT_NEAR(pixel->y(), image[0].y, 1e-7);
  }
  EXPECT_FALSE(lens.project({0.1, 0.1, -1.0}).has_value()) << "behind a pinhole";
}

TEST(Lens, UnprojectionInvertsProjectionBeyondNinetyDegrees) {
  const camera::Lens lens(wide(), 95.0 * std::numbers::pi / 180.0);
  for (double angle = 0.0; angle <= 94.9; angle += 4.75) {
    for (double azimuth = -3.0; azimuth < 3.2; azimuth += 0.7) {
      const Eigen::Vector3d ray = direction(angle * std::numbers::pi / 180.0, azimuth);
      const auto pixel = lens.project(2.0 * ray);
      ASSERT_TRUE(pixel.has_value()) << angle;
      const auto back = lens.unproject(pixel->x(), pixel->y());
      ASSERT_TRUE(back.has_value()) << angle;
      EXPECT_LT((*back - ray).norm(), 1e-9) << angle << " deg, azimuth " << azimuth;
    }
  }
  EXPECT_FALSE(lens.project(direction(96.0 * std::numbers::pi / 180.0, 0.3)).has_value()) << "beyond the field";
  EXPECT_FALSE(lens.unproject(0.0, 0.0).has_value()) << "the corner lies beyond 95 degrees";
}

TEST(Lens, PinholeUnprojectionInvertsTheStrongRadialDistortionOfFr1) {
  const camera::Lens lens(fr1());
  for (const auto& [u, v] : std::vector<std::pair<double, double>>{{0, 0}, {639, 479}, {320, 240}, {50.5, 400.25}}) {
    const auto ray = lens.unproject(u, v);
    ASSERT_TRUE(ray.has_value()) << u << "," << v;
    const auto pixel = lens.project(*ray);
    ASSERT_TRUE(pixel.has_value());
    EXPECT_NEAR(pixel->x(), u, 1e-6);
    EXPECT_NEAR(pixel->y(), v, 1e-6);
  }
}

TEST(VirtualViews, NineViewsCoverTheWideFieldAndMapBackOntoIt) {
  const camera::VirtualViews views(wide(), fr1());
  ASSERT_EQ(views.count(), 9);
  EXPECT_EQ(views.view_camera().distortion, (std::array<double, 5>{}));
  EXPECT_DOUBLE_EQ(views.coverage(4), 1.0) << "the middle view lies inside the wide image";
  EXPECT_TRUE(views.R_wide_view(4).isIdentity(1e-12));
  // Neighbours overlap by a share of a view: the right view's left edge lies left of the middle
  // view's right edge.
  const Eigen::Vector3d right_view_left_edge = views.ray(5, 0.0, 240.0);
  const Eigen::Vector3d middle_view_right_edge = views.ray(4, 639.0, 240.0);
  EXPECT_LT(std::atan2(right_view_left_edge.x(), right_view_left_edge.z()),
            std::atan2(middle_view_right_edge.x(), middle_view_right_edge.z()));
  const camera::Lens& lens = views.wide_lens();
  for (int i = 0; i < views.count(); ++i) {
    EXPECT_GT(views.coverage(i), 0.5) << "view " << i;
    for (const auto& [u, v] : std::vector<std::pair<double, double>>{{320, 240}, {10.5, 20}, {600, 470}}) {
      const auto pixel = views.wide_pixel(i, u, v);
      if (!pixel) continue;
      const auto ray = lens.unproject(pixel->x(), pixel->y());
      ASSERT_TRUE(ray.has_value());
      EXPECT_LT((*ray - views.ray(i, u, v)).norm(), 1e-9) << "view " << i << " at " << u << "," << v;
    }
  }
}

TEST(VirtualViews, RenderSamplesTheWideImageWhereTheTablesPoint) {
  const camera::VirtualViews views(wide(), fr1());
  cv::Mat image(600, 960, CV_8UC1);
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) image.at<unsigned char>(y, x) = static_cast<unsigned char>((x / 8 + y / 8) % 2 * 200 + 20);
  }
  std::vector<cv::Mat> rendered;
  views.allocate(rendered, CV_8UC1);
  const unsigned char* data = rendered[0].data;
  ASSERT_TRUE(views.render(image, rendered));
  EXPECT_EQ(rendered[0].data, data) << "render draws into the views allocate() made";
  int compared = 0;
  for (int i = 0; i < views.count(); ++i) {
    for (int v = 5; v < 480; v += 37) {
      for (int u = 5; u < 640; u += 41) {
        const auto pixel = views.wide_pixel(i, u, v);
        if (!pixel || pixel->x() < 1 || pixel->y() < 1 || pixel->x() > 958 || pixel->y() > 598) continue;
        cv::Mat sample;
        cv::getRectSubPix(image, cv::Size(1, 1), cv::Point2f(static_cast<float>(pixel->x()), static_cast<float>(pixel->y())),
                          sample, CV_32F);
        // The fixed-point tables place a sample to 1/32 pixel in each axis: up to 2 × 180/64 grey
        // levels at a corner of the pattern, plus rounding.
        EXPECT_NEAR(rendered[static_cast<std::size_t>(i)].at<unsigned char>(v, u), sample.at<float>(0, 0), 6.2)
            << "view " << i << " at " << u << "," << v;
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 1000);
  EXPECT_FALSE(views.render(image(cv::Rect(0, 0, 640, 480)), rendered)) << "a wrong-sized wide image";
  cv::Mat colour(600, 960, CV_8UC3, cv::Scalar::all(0));
  EXPECT_FALSE(views.render(colour, rendered)) << "views sized for another type";
}

}  // namespace
}  // namespace rankslam::slam
