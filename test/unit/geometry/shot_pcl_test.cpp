// SHOT against its reference implementation, PCL's pcl::SHOTEstimation, on the same keypoints,
// support points, normals and radius. Built only when PCL is installed (test-only dependency).

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>
#include <pcl/features/shot.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>

#include "rankslam/geometry/frontend.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "synthetic_scene.hpp"
#include "test_data.hpp"

namespace rankslam::geometry {
namespace {

// Cosine similarity of each of our descriptors with PCL's for the same keypoint.
std::vector<double> compare_with_pcl(const camera::DepthCameraModel& camera, const cv::Mat& depth,
                                     KeypointMethod method) {
  GeometryConfig config;
  GeometricFrontend frontend;
  EXPECT_EQ(frontend.configure(camera, config), "");
  GeometricFeatures features = frontend.make_features();
  EXPECT_EQ(frontend.extract(depth, method, features), GeometryStatus::kOk);
  const SampledCloud& cloud = frontend.last_cloud();
  pcl::PointCloud<pcl::PointXYZ>::Ptr surface(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::PointCloud<pcl::PointXYZ>::Ptr keypoints(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::PointCloud<pcl::Normal>::Ptr normals(new pcl::PointCloud<pcl::Normal>);
  for (int i = 0; i < cloud.size; ++i) {
    const Eigen::Vector3f& p = cloud.points[static_cast<std::size_t>(i)];
    const Eigen::Vector3f& n = cloud.normals[static_cast<std::size_t>(i)];
    surface->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    pcl::Normal normal;
    normal.normal_x = n.x();
    normal.normal_y = n.y();
    normal.normal_z = n.z();
    normals->push_back(normal);
  }
  for (int k = 0; k < features.count; ++k) {
    const Eigen::Vector3f& p = features.points_cam[static_cast<std::size_t>(k)];
    keypoints->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  }
  pcl::SHOTEstimation<pcl::PointXYZ, pcl::Normal, pcl::SHOT352> shot;
  shot.setInputCloud(keypoints);
  shot.setSearchSurface(surface);
  shot.setInputNormals(normals);
  shot.setRadiusSearch(config.shot_radius_m);
  shot.setSearchMethod(pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  pcl::PointCloud<pcl::SHOT352> reference;
  shot.compute(reference);
  EXPECT_EQ(static_cast<int>(reference.size()), features.count);
  std::vector<double> similarity;
  for (int k = 0; k < features.count; ++k) {
    double dot = 0.0, na = 0.0, nb = 0.0;
    for (int j = 0; j < kShotSize; ++j) {
      const auto a = static_cast<double>(features.descriptor(k)[j]);
      const auto b = static_cast<double>(reference[static_cast<std::size_t>(k)].descriptor[j]);
      dot += a * b;
      na += a * a;
      nb += b * b;
    }
    similarity.push_back(dot / std::sqrt(na * nb));
  }
  std::sort(similarity.begin(), similarity.end());
  return similarity;
}

void expect_pcl_agreement(const std::vector<double>& similarity) {
  ASSERT_FALSE(similarity.empty());
  EXPECT_GE(similarity[similarity.size() / 2], 0.99);  // the acceptance: median ≥ 0.99
  EXPECT_GE(similarity[similarity.size() / 20], 0.99);  // and nearly every descriptor
  std::printf("SHOT vs PCL: %zu descriptors, cosine min %.6f, 5th pct %.6f, median %.6f\n",
              similarity.size(), similarity.front(), similarity[similarity.size() / 20],
              similarity[similarity.size() / 2]);
}

TEST(ShotVsPcl, SyntheticRoom) {
  const camera::DepthCameraModel camera(testing::test_calibration(), 5000.0);
  const cv::Mat depth = testing::render_depth(
      testing::room_corner(), testing::test_calibration(),
      testing::look_at(Eigen::Vector3d(2.6, 2.4, 1.7), Eigen::Vector3d(0.9, 0.9, 0.3)), 1.4e-3);
  for (const KeypointMethod method : {KeypointMethod::kIs3d, KeypointMethod::kRos}) {
    expect_pcl_agreement(compare_with_pcl(camera, depth, method));
  }
}

TEST(ShotVsPcl, RealTumFrames) {
  hal::Calibration calibration;
  const std::vector<cv::Mat> frames = testing::tum_depth_frames("fr1_desk_9", 3, calibration);
  if (frames.empty()) GTEST_SKIP() << "shared data (RANKSLAM_SHARED_DATA/tum/fr1_desk_9) is absent";
  const camera::DepthCameraModel camera(calibration.rgb, calibration.depth_scale);
  for (const cv::Mat& depth : frames) {
    expect_pcl_agreement(compare_with_pcl(camera, depth, KeypointMethod::kIs3d));
  }
}

}  // namespace
}  // namespace rankslam::geometry
