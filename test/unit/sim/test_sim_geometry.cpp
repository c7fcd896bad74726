// Depth and ground truth describe the scene exactly: back-projected depth lands on the known
// surfaces, and two frames agree on where things are.
#include "sim_test_support.hpp"

#include "rankslam/sim/scene.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <functional>
#include <ostream>

namespace rankslam::sim {
namespace {

using testing::TempDir;

struct Frame {
  cv::Mat depth;
  Eigen::Isometry3d T_world_cam;
};

struct Written {
  hal::Calibration calibration;
  std::vector<Frame> frames;
};

Written load(const std::filesystem::path& dir) {
  Written written;
  written.calibration = testing::read_calibration(dir / "calibration.yaml");
  const auto depth = testing::read_rows(dir / "depth.txt");
  const auto gt = testing::read_groundtruth(dir / "groundtruth.txt");
  EXPECT_EQ(depth.size(), gt.size());
  for (std::size_t i = 0; i < depth.size() && i < gt.size(); ++i) {
    EXPECT_NEAR(std::stod(depth[i][0]), gt[i].stamp_s, 1e-6);
    written.frames.push_back({cv::imread((dir / depth[i][1]).string(), cv::IMREAD_UNCHANGED), gt[i].T});
  }
  return written;
}

double percentile(std::vector<double> values, double p) {
  if (values.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(p * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

struct GeometryCase {
  std::string scene;
  int first_frame;
};

void PrintTo(const GeometryCase& c, std::ostream* os) { *os << c.scene << " from frame " << c.first_frame; }

class SimGeometry : public ::testing::TestWithParam<GeometryCase> {};

TEST_P(SimGeometry, NoiseFreeDepthLiesOnTheSceneSurfacesAndFramesAgree) {
  const auto& param = GetParam();
  TempDir dir(param.scene);
  auto options = testing::options_for(param.scene, dir.path(), 8);
  options.first_frame = param.first_frame;
  options.sensor_noise = false;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  const Written written = load(dir.path());
  ASSERT_EQ(written.frames.size(), 8U);
  std::string error;
  const auto scene = make_scene(param.scene, options.seed, &error);
  ASSERT_TRUE(scene) << error;
  const auto& camera = written.calibration.rgb;
  const double scale = written.calibration.depth_scale;

  // 1. Every valid depth pixel, back-projected and moved by the ground truth, is on a surface
  //    (depth is stored in 0.2 mm units).
  for (const std::size_t f : {std::size_t{0}, std::size_t{7}}) {
    const Frame& frame = written.frames[f];
    int valid = 0;
    int checked = 0;
    double worst = 0.0;
    for (int v = 0; v < frame.depth.rows; v += 3) {
      for (int u = 0; u < frame.depth.cols; u += 3) {
        const auto raw = frame.depth.at<std::uint16_t>(v, u);
        ++checked;
        if (raw == 0) continue;
        ++valid;
        const Eigen::Vector3d p = frame.T_world_cam * testing::back_project(camera, u, v, raw / scale);
        worst = std::max(worst, scene->distance_to_surface_m(p));
      }
    }
    EXPECT_GT(valid, checked / 2) << "frame " << f;
    EXPECT_LT(worst, 1e-3) << "frame " << f << ": a depth pixel is " << worst << " m off every surface";
  }

  // 2. Points of the last frame, projected into the first, meet the first frame's depth there.
  const Frame& a = written.frames.front();
  const Frame& b = written.frames.back();
  const double moved = (a.T_world_cam.translation() - b.T_world_cam.translation()).norm() +
                       Eigen::AngleAxisd(a.T_world_cam.linear().transpose() * b.T_world_cam.linear()).angle();
  EXPECT_GT(moved, 0.01) << "the frames should see the scene from different poses";
  const Eigen::Isometry3d T_a_b = a.T_world_cam.inverse() * b.T_world_cam;
  std::vector<double> relative_errors;
  for (int v = 0; v < b.depth.rows; v += 4) {
    for (int u = 0; u < b.depth.cols; u += 4) {
      const auto raw = b.depth.at<std::uint16_t>(v, u);
      if (raw == 0) continue;
      const Eigen::Vector3d p_a = T_a_b * testing::back_project(camera, u, v, raw / scale);
      const double ua = camera.fx * p_a.x() / p_a.z() + camera.cx;
      const double va = camera.fy * p_a.y() / p_a.z() + camera.cy;
      const int iu = static_cast<int>(std::lround(ua));
      const int iv = static_cast<int>(std::lround(va));
      if (p_a.z() <= 0.0 || iu < 0 || iv < 0 || iu >= a.depth.cols || iv >= a.depth.rows) continue;
      const auto raw_a = a.depth.at<std::uint16_t>(iv, iu);
      if (raw_a == 0) continue;
      relative_errors.push_back(std::abs(raw_a / scale - p_a.z()) / p_a.z());
    }
  }
  ASSERT_GT(relative_errors.size(), 1000U);
  // Nearest-pixel lookup: slanted surfaces and occlusion edges make a few large errors.
  EXPECT_LT(percentile(relative_errors, 0.5), 0.003);
  EXPECT_LT(percentile(relative_errors, 0.9), 0.02);
}

INSTANTIATE_TEST_SUITE_P(Scenes, SimGeometry,
                         ::testing::Values(GeometryCase{"office", 0}, GeometryCase{"zigzag-plain", 20},
                                           GeometryCase{"poster-wall", 40}, GeometryCase{"corridor-loop", 150}),
                         [](const auto& test_info) {
                           std::string name = test_info.param.scene;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

TEST(SimGeometry, NoisyPosterWallDepthStaysOnItsPlaneWithinTheNoise) {
  TempDir dir("poster_noise");
  ASSERT_EQ(simulate_recording(testing::options_for("poster-wall", dir.path(), 2), nullptr), "");
  const Written written = load(dir.path());
  const auto& camera = written.calibration.rgb;
  int outside = 0;
  int total = 0;
  double sum = 0.0;
  for (const Frame& frame : written.frames) {
    for (int v = 0; v < frame.depth.rows; v += 2) {
      for (int u = 0; u < frame.depth.cols; u += 2) {
        const auto raw = frame.depth.at<std::uint16_t>(v, u);
        if (raw == 0) continue;
        const double z = raw / written.calibration.depth_scale;
        const Eigen::Vector3d p = frame.T_world_cam * testing::back_project(camera, u, v, z);
        // The wall is the plane y = 1.5 m; its distance along y is at most the depth error.
        const double error = p.y() - 1.5;
        // Kinect model: σ_z = 1.425e-3·z² plus 1/8 px disparity quantisation (σ = step/√12).
        const double quantisation = z * z / (580.0 * 0.075 * 8.0 * std::sqrt(12.0));
        const double sigma = std::hypot(1.425e-3 * z * z, quantisation) + 1e-4;
        sum += error;
        ++total;
        outside += std::abs(error) > 5.0 * sigma ? 1 : 0;
      }
    }
  }
  ASSERT_GT(total, 50000);
  EXPECT_LT(static_cast<double>(outside) / total, 0.001);
  EXPECT_LT(std::abs(sum / total), 1e-3) << "depth noise must be unbiased";
}

TEST(SimGeometry, CamerasProjectLikeTheirCalibrationSays) {
  // The corridor's ceiling lamps are the brightest things in view: projected with the written
  // calibration (OpenCV's own fisheye model for the wide-angle camera), they land on bright
  // pixels in both cameras.
  TempDir dir("lamps");
  ASSERT_EQ(simulate_recording(testing::options_for("corridor-loop", dir.path(), 1), nullptr), "");
  const hal::Calibration calibration = testing::read_calibration(dir / "calibration.yaml");
  ASSERT_TRUE(calibration.fisheye);
  const auto gt = testing::read_groundtruth(dir / "groundtruth.txt");
  ASSERT_EQ(gt.size(), 1U);
  const Eigen::Isometry3d T_world_base = gt[0].T * calibration.rgb.T_base_cam.inverse();
  const Eigen::Isometry3d T_world_fisheye = T_world_base * calibration.fisheye->T_base_cam;
  const cv::Mat rgb = cv::imread((dir / testing::read_rows(dir / "rgb.txt")[0][1]).string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat fisheye =
      cv::imread((dir / testing::read_rows(dir / "fisheye.txt")[0][1]).string(), cv::IMREAD_GRAYSCALE);
  // Where a lamp should appear: the pixels whose centre ray (from the written calibration,
  // OpenCV's own fisheye model for the wide-angle camera) meets the lamp's rectangle. Where it
  // does appear: the saturated pixels. Only rays grazing the outline may disagree.
  using RayFn = std::function<Eigen::Vector3d(double, double)>;  // pixel → ray in the camera frame
  auto expect_lamp_where_calibration_says = [](const cv::Mat& image, const SurfaceQuad& lamp,
                                               const Eigen::Isometry3d& T_world_cam, const cv::Rect& box,
                                               const RayFn& ray, const std::string& what) {
    const cv::Rect area = box & cv::Rect(0, 0, image.cols, image.rows);
    ASSERT_GT(area.area(), 16) << what;
    int expected = 0;
    int disagree = 0;
    for (int y = area.y; y < area.y + area.height; ++y) {
      for (int x = area.x; x < area.x + area.width; ++x) {
        const Eigen::Vector3d o = T_world_cam.translation();
        const Eigen::Vector3d d = T_world_cam.linear() * ray(x, y);
        const double t = (lamp.center_m - o).dot(lamp.normal()) / d.dot(lamp.normal());
        const Eigen::Vector3d p = o + t * d - lamp.center_m;
        const bool inside = t > 0.0 && std::abs(p.dot(lamp.axis_u)) <= lamp.half_u_m && std::abs(p.dot(lamp.axis_v)) <= lamp.half_v_m;
        expected += inside ? 1 : 0;
        disagree += inside != (image.at<std::uint8_t>(y, x) > 245) ? 1 : 0;
      }
    }
    EXPECT_GT(expected, 4) << what;
    EXPECT_LE(disagree, 1 + expected / 50) << what << ": " << disagree << " of " << expected << " lamp pixels differ";
  };
  auto box_of = [](const SurfaceQuad& lamp, const std::function<cv::Point2d(const Eigen::Vector3d&)>& project) {
    std::vector<cv::Point2f> corners;
    for (const double su : {-1.0, 1.0}) {
      for (const double sv : {-1.0, 1.0}) {
        const cv::Point2d uv = project(lamp.center_m + su * lamp.half_u_m * lamp.axis_u + sv * lamp.half_v_m * lamp.axis_v);
        corners.emplace_back(static_cast<float>(uv.x), static_cast<float>(uv.y));
      }
    }
    const cv::Rect box = cv::boundingRect(corners);
    return cv::Rect(box.x - 4, box.y - 4, box.width + 8, box.height + 8);
  };
  auto brightest_near = [](const cv::Mat& image, double u, double v) {
    const cv::Rect window = cv::Rect(static_cast<int>(std::lround(u)) - 2, static_cast<int>(std::lround(v)) - 2, 5, 5) &
                            cv::Rect(0, 0, image.cols, image.rows);
    double max_value = 0.0;
    if (window.area() > 0) cv::minMaxLoc(image(window), nullptr, &max_value);
    return max_value;
  };

  // The lamps over the first straight, ahead of the robot (centres of the lamp quads).
  std::string error;
  const auto scene = make_scene("corridor-loop", 1, &error);
  ASSERT_TRUE(scene) << error;
  const cv::Matx33d K(calibration.fisheye->fx, 0, calibration.fisheye->cx, 0, calibration.fisheye->fy,
                      calibration.fisheye->cy, 0, 0, 1);
  const cv::Vec4d D(calibration.fisheye->distortion[0], calibration.fisheye->distortion[1],
                    calibration.fisheye->distortion[2], calibration.fisheye->distortion[3]);
  int checked_fisheye = 0;
  int checked_rgb = 0;
  for (const auto& quad : scene->surfaces) {
    if (scene->materials[static_cast<std::size_t>(quad.material)].emission <= 0.0f) continue;
    if (std::abs(quad.center_m.y()) > 0.5 || quad.center_m.x() < 1.5) continue;
    const Eigen::Vector3d p_f = T_world_fisheye.inverse() * quad.center_m;
    ASSERT_GT(p_f.z(), 0.0);
    std::vector<cv::Point3d> object = {{p_f.x(), p_f.y(), p_f.z()}};
    std::vector<cv::Point2d> image;
    cv::fisheye::projectPoints(object, image, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, D);
    const std::string name = "lamp at x = " + std::to_string(quad.center_m.x());
    EXPECT_GT(brightest_near(fisheye, image[0].x, image[0].y), 200.0) << name << " projects to " << image[0];
    const auto project_fisheye = [&](const Eigen::Vector3d& p_world) {
      const Eigen::Vector3d p = T_world_fisheye.inverse() * p_world;
      std::vector<cv::Point3d> points = {{p.x(), p.y(), p.z()}};
      std::vector<cv::Point2d> pixels;
      cv::fisheye::projectPoints(points, pixels, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, D);
      return pixels[0];
    };
    const auto fisheye_ray = [&](double u, double v) {
      std::vector<cv::Point2d> distorted = {{u, v}};
      std::vector<cv::Point2d> normalised;
      cv::fisheye::undistortPoints(distorted, normalised, K, D);
      return Eigen::Vector3d(normalised[0].x, normalised[0].y, 1.0);
    };
    expect_lamp_where_calibration_says(fisheye, quad, T_world_fisheye, box_of(quad, project_fisheye), fisheye_ray,
                                       name + " (fisheye)");
    ++checked_fisheye;
    const auto project_rgb = [&](const Eigen::Vector3d& p_world) {
      const Eigen::Vector3d p = gt[0].T.inverse() * p_world;
      return cv::Point2d(calibration.rgb.fx * p.x() / p.z() + calibration.rgb.cx,
                         calibration.rgb.fy * p.y() / p.z() + calibration.rgb.cy);
    };
    const auto rgb_ray = [&](double u, double v) {
      return Eigen::Vector3d((u - calibration.rgb.cx) / calibration.rgb.fx, (v - calibration.rgb.cy) / calibration.rgb.fy, 1.0);
    };
    const cv::Rect box = box_of(quad, project_rgb);
    if ((box & cv::Rect(0, 0, rgb.cols, rgb.rows)) != box) continue;  // only lamps wholly in view
    expect_lamp_where_calibration_says(rgb, quad, gt[0].T, box, rgb_ray, name + " (rgb)");
    ++checked_rgb;
  }
  EXPECT_EQ(checked_fisheye, 3);
  EXPECT_GE(checked_rgb, 1);
  // And a patch of plain wall or floor is not that bright.
  EXPECT_LT(cv::mean(fisheye(cv::Rect(430, 500, 100, 60)))[0], 200.0);
}

}  // namespace
}  // namespace rankslam::sim
