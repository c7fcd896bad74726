#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <nanoflann.hpp>

#include "rankslam/geometry/cloud.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "synthetic_scene.hpp"

namespace rankslam::geometry {
namespace {

struct DenseCloud {
  std::vector<Eigen::Vector3f> pts;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return pts.size(); }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t d) const { return pts[i][static_cast<Eigen::Index>(d)]; }
  template <class B>
  bool kdtree_get_bbox(B& /*bb*/) const { return false; }
};
using DenseTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, DenseCloud>, DenseCloud, 3>;

DenseCloud pass_through_cloud(const cv::Mat& depth, const camera::DepthCameraModel& camera, float max_m) {
  DenseCloud cloud;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const auto raw = depth.at<std::uint16_t>(v, u);
      if (raw == 0) continue;
      const float z = camera.metres(raw);
      if (z > max_m) continue;
      cloud.pts.push_back(camera.back_project(u, v, z));
    }
  }
  return cloud;
}

class CloudTest : public ::testing::Test {
 protected:
  void SetUp() override {
    camera_ = camera::DepthCameraModel(testing::test_calibration(), 5000.0);
    eye_ = Eigen::Vector3d(2.6, 2.4, 1.7);
    depth_ = testing::render_depth(testing::room_corner(), testing::test_calibration(),
                                   testing::look_at(eye_, Eigen::Vector3d(0.9, 0.9, 0.3)), 1.4e-3);
    ASSERT_EQ(preprocessor_.configure(camera_, config_, 16384), "");
    cloud_ = preprocessor_.make_cloud();
  }

  camera::DepthCameraModel camera_;
  Eigen::Vector3d eye_;
  cv::Mat depth_;
  GeometryConfig config_;
  CloudPreprocessor preprocessor_;
  SampledCloud cloud_;
};

TEST_F(CloudTest, ResolutionMatchesTheExactMeanNearestNeighbourDistance) {
  const DenseCloud dense = pass_through_cloud(depth_, camera_, 4.0F);
  DenseTree tree(3, dense, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  double sum = 0.0;
  for (std::size_t i = 0; i < dense.pts.size(); ++i) {
    std::array<std::uint32_t, 2> index{};
    std::array<float, 2> d2{};
    tree.knnSearch(dense.pts[i].data(), 2, index.data(), d2.data());
    sum += std::sqrt(static_cast<double>(d2[1]));  // [0] is the point itself
  }
  const double exact = sum / static_cast<double>(dense.pts.size());
  const double organised = organised_resolution(depth_, camera_, config_.resolution_pixel_stride, 0.0F, 4.0F);
  EXPECT_NEAR(organised, exact, 0.03 * exact) << "exact " << exact;
  // The preprocessor's estimate, its rows on a thread team, is the same value.
  parallel::ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  CloudPreprocessor shared;
  GeometryConfig config = config_;
  config.min_depth_m = 0.0;
  config.max_depth_m = 4.0;
  ASSERT_EQ(shared.configure(camera_, config, 16384, &team), "");
  SampledCloud cloud = shared.make_cloud();
  ASSERT_EQ(shared.process(depth_, cloud), GeometryStatus::kOk);
  EXPECT_EQ(cloud.resolution_m, static_cast<float>(organised));
}

// At the default leaf, and at a small one that makes each band's hash table double the slots
// it uses more than once (over 10 000 voxels).
TEST_F(CloudTest, VoxelCentroidsMatchABruteForceVoxelGrid) {
  for (const double leaf_factor : {config_.voxel_leaf_factor, 6.0}) {
    SCOPED_TRACE(::testing::Message() << "leaf factor " << leaf_factor);
    GeometryConfig config = config_;
    config.voxel_leaf_factor = leaf_factor;
    CloudPreprocessor preprocessor;
    ASSERT_EQ(preprocessor.configure(camera_, config, 16384), "");
    SampledCloud cloud = preprocessor.make_cloud();
    ASSERT_EQ(preprocessor.process(depth_, cloud), GeometryStatus::kOk);
    const float leaf = cloud.voxel_leaf_m;
    EXPECT_NEAR(leaf, leaf_factor * static_cast<double>(cloud.resolution_m), 1e-6);
    // Reference: every pass-through pixel into its voxel, centroids in double.
    const float inverse = 1.0F / leaf;
    std::map<std::tuple<long, long, long>, std::pair<Eigen::Vector3d, int>> voxels;
    const DenseCloud dense = pass_through_cloud(depth_, camera_, 4.0F);
    for (const Eigen::Vector3f& p : dense.pts) {
      const auto key = std::make_tuple(static_cast<long>(std::floor(static_cast<double>(p.x() * inverse))),
                                       static_cast<long>(std::floor(static_cast<double>(p.y() * inverse))),
                                       static_cast<long>(std::floor(static_cast<double>(p.z() * inverse))));
      auto& entry = voxels.try_emplace(key, Eigen::Vector3d::Zero(), 0).first->second;
      entry.first += p.cast<double>();
      ++entry.second;
    }
    EXPECT_EQ(cloud.dense_points, static_cast<int>(dense.pts.size()));
    EXPECT_EQ(cloud.size + cloud.dropped_normals, static_cast<int>(voxels.size()));
    EXPECT_GT(cloud.size, leaf_factor < 10.0 ? 10000 : 1000);
    for (int i = 0; i < cloud.size; ++i) {
      const Eigen::Vector3f& c = cloud.points[static_cast<std::size_t>(i)];
      const auto key = std::make_tuple(static_cast<long>(std::floor(static_cast<double>(c.x() * inverse))),
                                       static_cast<long>(std::floor(static_cast<double>(c.y() * inverse))),
                                       static_cast<long>(std::floor(static_cast<double>(c.z() * inverse))));
      const auto it = voxels.find(key);
      ASSERT_NE(it, voxels.end()) << "centroid " << i << " in no reference voxel";
      const Eigen::Vector3d reference = it->second.first / it->second.second;
      EXPECT_LT((reference - c.cast<double>()).norm(), 1e-5) << "voxel " << i;
      EXPECT_EQ(cloud.dense_counts[static_cast<std::size_t>(i)], it->second.second);
    }
  }
}

// The 4 x 4 blocks' means, bounds and point counts (the normals' input) against a plain pass
// over each block's pixels in pixel order, on a frame with holes and a width that is not a
// whole number of 8-block groups: the vectorised rows and their portable tail alike. Blocks
// across a depth edge are its two parts, split at the middle of their depths.
TEST_F(CloudTest, BlockMeansAndBoundsMatchAPlainPassOverTheirPixels) {
  hal::CameraCalibration calibration = testing::test_calibration();
  calibration.width = 628;  // 157 blocks: 19 groups of 8 and 5 more
  calibration.cx = 313.5;
  const camera::DepthCameraModel camera(calibration, 5000.0);
  cv::Mat depth = testing::render_depth(testing::room_corner(), calibration,
                                        testing::look_at(eye_, Eigen::Vector3d(0.9, 0.9, 0.3)), 1.4e-3);
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = (v * 3) % 7; u < depth.cols; u += 7) depth.at<std::uint16_t>(v, u) = 0;  // holes
  }
  CloudPreprocessor preprocessor;
  ASSERT_EQ(preprocessor.configure(camera, config_, 16384), "");
  SampledCloud cloud = preprocessor.make_cloud();
  ASSERT_EQ(preprocessor.process(depth, cloud), GeometryStatus::kOk);
  const BlockImage& blocks = preprocessor.blocks();
  const auto max_m = static_cast<float>(config_.max_depth_m);
  int checked = 0;
  int split = 0;
  for (int bv = 0; bv < blocks.height; ++bv) {
    for (int bu = 0; bu < blocks.width; ++bu) {
      std::vector<Eigen::Vector3f> points;
      for (int v = bv * BlockImage::kBlock; v < std::min((bv + 1) * BlockImage::kBlock, depth.rows); ++v) {
        for (int u = bu * BlockImage::kBlock; u < std::min((bu + 1) * BlockImage::kBlock, depth.cols); ++u) {
          const auto raw = depth.at<std::uint16_t>(v, u);
          if (raw == 0) continue;
          const float z = camera.metres(raw);
          if (z > max_m) continue;
          points.push_back(camera.back_project(u, v, z));
        }
      }
      // The mean, centre and half extent of the points (nearer than split_z, or farther).
      const auto expect_layer = [&](const BlockImage::Layer& layer, std::size_t b, float split_z, bool near) {
        Eigen::Vector3f sum = Eigen::Vector3f::Zero();
        Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
        Eigen::Vector3f hi = -lo;
        int count = 0;
        for (const Eigen::Vector3f& p : points) {
          if ((p.z() <= split_z) != near) continue;
          sum += p;
          lo = lo.cwiseMin(p);
          hi = hi.cwiseMax(p);
          ++count;
        }
        ASSERT_EQ(layer.weight[b], static_cast<float>(count));
        ASSERT_EQ(layer.mean(b), sum / static_cast<float>(count));
        ASSERT_EQ(Eigen::Vector3f(layer.centre_x[b], layer.centre_y[b], layer.centre_z[b]), 0.5F * (lo + hi));
        ASSERT_EQ(Eigen::Vector3f(layer.half_x[b], layer.half_y[b], layer.half_z[b]), 0.5F * (hi - lo));
      };
      const std::size_t b = blocks.index(bu, bv);
      SCOPED_TRACE(::testing::Message() << "block " << bu << ", " << bv);
      ASSERT_EQ(blocks.front.weight[b] + blocks.back.weight[b], static_cast<float>(points.size()));
      if (points.empty()) continue;
      if (blocks.across_depth_edge(b)) {
        // Split at the middle of its depths into a near part (front) and a far part (back).
        float z_min = std::numeric_limits<float>::infinity();
        float z_max = -z_min;
        for (const Eigen::Vector3f& p : points) {
          z_min = std::min(z_min, p.z());
          z_max = std::max(z_max, p.z());
        }
        const float split_z = 0.5F * (z_min + z_max);
        expect_layer(blocks.front, b, split_z, true);
        expect_layer(blocks.back, b, split_z, false);
        ++split;
      } else {
        expect_layer(blocks.front, b, std::numeric_limits<float>::infinity(), true);
        ++checked;
      }
    }
  }
  EXPECT_GT(split, 0) << "the room corner's box should make depth edges";
  EXPECT_GT(checked, blocks.width * blocks.height / 2);
}

TEST_F(CloudTest, PassThroughDropsFarPoints) {
  // The room without its walls, and a wall 5–6 m away behind it.
  testing::Scene scene = testing::room_corner();
  scene.rectangles.erase(scene.rectangles.begin() + 1, scene.rectangles.begin() + 3);
  scene.rectangles.push_back({Eigen::Vector3d(-3.0, 2.0, 1.0), Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ(), 6.0, 6.0});
  const cv::Mat depth = testing::render_depth(scene, testing::test_calibration(),
                                              testing::look_at(Eigen::Vector3d(2.6, 2.4, 1.7), Eigen::Vector3d(-1.0, 1.5, 0.8)));
  int far_pixels = 0;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) far_pixels += depth.at<std::uint16_t>(v, u) > 4.0 * 5000.0 ? 1 : 0;
  }
  ASSERT_GT(far_pixels, 10000);
  ASSERT_EQ(preprocessor_.process(depth, cloud_), GeometryStatus::kOk);
  for (int i = 0; i < cloud_.size; ++i) EXPECT_LE(cloud_.points[static_cast<std::size_t>(i)].z(), 4.0F);
  EXPECT_EQ(cloud_.dense_points, static_cast<int>(pass_through_cloud(depth, camera_, 4.0F).pts.size()));
}

TEST_F(CloudTest, NormalsAreUnitAndFaceTheCamera) {
  ASSERT_EQ(preprocessor_.process(depth_, cloud_), GeometryStatus::kOk);
  for (int i = 0; i < cloud_.size; ++i) {
    const Eigen::Vector3f& n = cloud_.normals[static_cast<std::size_t>(i)];
    EXPECT_NEAR(n.norm(), 1.0F, 1e-4F);
    EXPECT_LT(n.dot(cloud_.points[static_cast<std::size_t>(i)]), 0.0F) << "point " << i;
  }
}

TEST_F(CloudTest, PlaneNormalsAreExactOnNoiseFreeData) {
  const Eigen::Isometry3d T_world_cam = testing::look_at(eye_, Eigen::Vector3d(2.0, 2.0, 0.0));
  testing::Scene floor_only;
  floor_only.rectangles.push_back(testing::room_corner().rectangles.front());
  const cv::Mat depth = testing::render_depth(floor_only, testing::test_calibration(), T_world_cam);
  ASSERT_EQ(preprocessor_.process(depth, cloud_), GeometryStatus::kOk);
  const Eigen::Vector3f up_cam = (T_world_cam.linear().transpose() * Eigen::Vector3d::UnitZ()).cast<float>();
  int checked = 0;
  for (int i = 0; i < cloud_.size; ++i) {
    const Eigen::Vector2f px = cloud_.pixels[static_cast<std::size_t>(i)];
    if (px.x() < 60 || px.x() > 580 || px.y() < 60 || px.y() > 420) continue;  // away from the image border
    EXPECT_GT(cloud_.normals[static_cast<std::size_t>(i)].dot(up_cam), std::cos(0.2 * M_PI / 180.0)) << i;  // 0.2 mm depth steps
    EXPECT_LT(cloud_.curvature[static_cast<std::size_t>(i)], 1e-4F);
    ++checked;
  }
  EXPECT_GT(checked, 500);
}

TEST_F(CloudTest, AdaptiveLeafKeepsThePointCountSteady) {
  // The same room seen from 1.5 m and from 3 m: the leaf scales with the resolution.
  const cv::Mat near = testing::render_depth(testing::room_corner(), testing::test_calibration(),
                                             testing::look_at(Eigen::Vector3d(2.0, 2.0, 1.3), Eigen::Vector3d(0.9, 0.9, 0.3)), 1.4e-3);
  const cv::Mat far = testing::render_depth(testing::room_corner(), testing::test_calibration(),
                                            testing::look_at(Eigen::Vector3d(3.4, 3.2, 2.0), Eigen::Vector3d(0.9, 0.9, 0.3)), 1.4e-3);
  ASSERT_EQ(preprocessor_.process(near, cloud_), GeometryStatus::kOk);
  const int near_count = cloud_.size;
  const float near_leaf = cloud_.voxel_leaf_m;
  ASSERT_EQ(preprocessor_.process(far, cloud_), GeometryStatus::kOk);
  EXPECT_GT(cloud_.voxel_leaf_m, 1.3F * near_leaf);
  EXPECT_NEAR(cloud_.size, near_count, 0.35 * near_count);
  EXPECT_GT(cloud_.size, 2000);
  EXPECT_LT(cloud_.size, 9000);
}

TEST_F(CloudTest, BadImagesAreRejected) {
  EXPECT_EQ(preprocessor_.process(cv::Mat(), cloud_), GeometryStatus::kInvalidImage);
  EXPECT_EQ(preprocessor_.process(cv::Mat(480, 640, CV_8UC1, cv::Scalar(1)), cloud_), GeometryStatus::kInvalidImage);
  EXPECT_EQ(preprocessor_.process(cv::Mat(240, 320, CV_16UC1, cv::Scalar(5000)), cloud_), GeometryStatus::kInvalidImage);
  EXPECT_EQ(preprocessor_.process(cv::Mat(480, 640, CV_16UC1, cv::Scalar(0)), cloud_), GeometryStatus::kTooFewPoints);
  SampledCloud small;
  EXPECT_EQ(preprocessor_.process(depth_, small), GeometryStatus::kCapacityExceeded);
  CloudPreprocessor unconfigured;
  EXPECT_EQ(unconfigured.process(depth_, cloud_), GeometryStatus::kNotConfigured);
}

TEST_F(CloudTest, ConfigureNamesTheProblem) {
  GeometryConfig bad;
  bad.voxel_leaf_factor = -1.0;
  CloudPreprocessor preprocessor;
  EXPECT_NE(preprocessor.configure(camera_, bad, 100).find("voxel_leaf_factor"), std::string::npos);
  EXPECT_NE(preprocessor.configure(camera::DepthCameraModel(), GeometryConfig{}, 100).find("image size"), std::string::npos);
  EXPECT_NE(preprocessor.configure(camera_, GeometryConfig{}, 1).find("max_sampled_points"), std::string::npos);
}

}  // namespace
}  // namespace rankslam::geometry
