#include "rankslam/slam/icp.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>

namespace rankslam::slam {
namespace {

hal::CameraCalibration pinhole() {
  hal::CameraCalibration camera;
  camera.fx = camera.fy = 525.0;
  camera.cx = 319.5;
  camera.cy = 239.5;
  return camera;
}

struct Plane {
  Eigen::Vector3d normal;
  double offset;  // n·X = offset
};

// A room corner in front of the camera: back wall, floor, left wall and a box on the floor, so
// that every rotation and translation is constrained.
const std::array<Plane, 6> kScene = {{
    {Eigen::Vector3d(0, 0, 1), 2.6},    // back wall
    {Eigen::Vector3d(0, 1, 0), 0.7},    // floor (y down)
    {Eigen::Vector3d(1, 0, 0), -0.9},   // left wall
    {Eigen::Vector3d(0, 0, 1), 1.9},    // box front
    {Eigen::Vector3d(1, 0, 0), 0.25},   // box side
    {Eigen::Vector3d(0, 1, 0), 0.35},   // box top
}};

bool inside_box(const Eigen::Vector3d& p) {
  return p.x() >= -0.05 - 1e-6 && p.x() <= 0.25 + 1e-6 && p.y() >= 0.35 - 1e-6 && p.y() <= 0.7 + 1e-6 &&
         p.z() >= 1.9 - 1e-6 && p.z() <= 2.2 + 1e-6;
}

// Depth image (raw units, 5000 per metre) of the scene seen from T_world_cam.
cv::Mat render(const Eigen::Isometry3d& T_world_cam) {
  const hal::CameraCalibration camera = pinhole();
  cv::Mat depth(camera.height, camera.width, CV_16UC1, cv::Scalar(0));
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector3d ray((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0);
      const Eigen::Vector3d origin = T_world_cam.translation();
      const Eigen::Vector3d direction = T_world_cam.linear() * ray;
      double best = 1e9;
      for (std::size_t k = 0; k < kScene.size(); ++k) {
        const double along = kScene[k].normal.dot(direction);
        if (std::abs(along) < 1e-9) continue;
        const double t = (kScene[k].offset - kScene[k].normal.dot(origin)) / along;
        if (t <= 0.1 || t >= best) continue;
        const Eigen::Vector3d hit = origin + t * direction;
        const bool box_face = k >= 3;
        if (box_face != inside_box(hit)) continue;  // box faces exist only on the box
        if (k < 3 && (hit.z() > 2.6 + 1e-6 || hit.y() > 0.7 + 1e-6 || hit.x() < -0.9 - 1e-6)) continue;
        best = t;  // ray z = 1, so t is the depth along the optical axis
      }
      if (best < 1e8) depth.at<unsigned short>(v, u) = static_cast<unsigned short>(std::lround(best * 5000.0));
    }
  }
  return depth;
}

Eigen::Isometry3d small_motion() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.03, Eigen::Vector3d(0.3, 1.0, 0.2).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.03, -0.015, 0.02);
  return T;
}

class IcpModes : public ::testing::TestWithParam<IcpMode> {};

TEST_P(IcpModes, RecoversAKnownMotionFromDepthAlone) {
  const camera::DepthCameraModel camera(pinhole(), 5000.0);
  IcpSettings settings;
  settings.mode = GetParam();
  settings.max_iterations = 50;
  IcpRefiner icp(settings, camera);
  VoxelCloud target;
  VoxelCloud source;
  for (VoxelCloud* cloud : {&target, &source}) {
    cloud->points.reserve(icp.cloud_capacity());
    cloud->normals.reserve(icp.cloud_capacity());
  }
  const Eigen::Isometry3d T_target_source = small_motion();
  icp.build_cloud(render(Eigen::Isometry3d::Identity()), target);
  icp.build_cloud(render(T_target_source), source);
  ASSERT_GT(target.size(), 1000U);
  ASSERT_LE(target.size(), icp.cloud_capacity());
  if (GetParam() == IcpMode::kPointToPlane) {
    ASSERT_EQ(target.normals.size(), target.size());
    for (const Eigen::Vector3f& n : target.normals) ASSERT_NEAR(n.norm(), 1.0F, 1e-4F);
  }
  icp.set_target(target, 1);

  // Start from the motion with 1 cm and 1° of error, as a feature estimate might have.
  Eigen::Isometry3d initial = T_target_source;
  initial.translation() += Eigen::Vector3d(0.01, 0.0, -0.005);
  initial.linear() = Eigen::AngleAxisd(0.017, Eigen::Vector3d::UnitX()).toRotationMatrix() * initial.linear();
  const IcpResult result = icp.align(source, initial);
  ASSERT_TRUE(result.ok) << result.failure_reason;
  const Eigen::Isometry3d error = T_target_source.inverse() * result.T_target_source;
  EXPECT_LT(error.translation().norm(), 0.004);
  EXPECT_LT(Eigen::AngleAxisd(error.rotation()).angle(), 0.2 * M_PI / 180.0);
  EXPECT_GT(result.correspondences, 500);
}

INSTANTIATE_TEST_SUITE_P(Modes, IcpModes, ::testing::Values(IcpMode::kPointToPoint, IcpMode::kPointToPlane),
                         [](const auto& param_info) { return std::string(to_string(param_info.param)); });

TEST(IcpRefiner, VoxelCloudDropsInvalidAndFarDepth) {
  const camera::DepthCameraModel camera(pinhole(), 5000.0);
  IcpSettings settings;
  settings.mode = IcpMode::kPointToPoint;
  IcpRefiner icp(settings, camera);
  VoxelCloud cloud;
  cloud.points.reserve(icp.cloud_capacity());
  cv::Mat depth(480, 640, CV_16UC1, cv::Scalar(0));
  depth(cv::Rect(0, 0, 320, 480)).setTo(cv::Scalar(5.0 * 5000.0));   // beyond 4 m
  depth(cv::Rect(320, 0, 100, 100)).setTo(cv::Scalar(1.0 * 5000.0));  // 1 m
  icp.build_cloud(depth, cloud);
  ASSERT_FALSE(cloud.points.empty());
  for (const Eigen::Vector3f& p : cloud.points) {
    EXPECT_NEAR(p.z(), 1.0F, 0.011F);  // centroids of points on the 1 m plane only
    EXPECT_GT(p.x(), 0.0F);
  }
  // 100×100 px at 1 m is about 0.19 m square: about ten 2 cm voxels a side.
  EXPECT_GT(cloud.size(), 60U);
  EXPECT_LT(cloud.size(), 200U);

  icp.build_cloud(cv::Mat(), cloud);
  EXPECT_TRUE(cloud.points.empty());
  icp.set_target(cloud, 2);
  EXPECT_FALSE(icp.align(cloud, Eigen::Isometry3d::Identity()).ok);
}

TEST(IcpMode, NamesParseBack) {
  for (const IcpMode mode : {IcpMode::kOff, IcpMode::kPointToPoint, IcpMode::kPointToPlane}) {
    EXPECT_EQ(parse_icp_mode(to_string(mode)), mode);
  }
  EXPECT_FALSE(parse_icp_mode("plane").has_value());
}

}  // namespace
}  // namespace rankslam::slam
