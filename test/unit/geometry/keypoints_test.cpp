#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/geometry/cloud.hpp"
#include "rankslam/geometry/keypoints.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "synthetic_scene.hpp"

namespace rankslam::geometry {
namespace {

double segment_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

// Distance from a world point to the room corner's creases (floor and wall joints, box edges) or
// to its sphere: where surface normals change.
double distance_to_structure(const Eigen::Vector3d& p) {
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> edges = {
      {{0, 0, 0}, {4, 0, 0}}, {{0, 0, 0}, {0, 4, 0}}, {{0, 0, 0}, {0, 0, 2.5}}};
  const double lo = 0.75;
  const double hi = 1.25;
  for (const double a : {lo, hi}) {
    for (const double b : {lo, hi}) {
      edges.push_back({{a, b, 0.0}, {a, b, 0.5}});    // vertical box edges
      edges.push_back({{a, lo, b == lo ? 0.0 : 0.5}, {a, hi, b == lo ? 0.0 : 0.5}});
      edges.push_back({{lo, a, b == lo ? 0.0 : 0.5}, {hi, a, b == lo ? 0.0 : 0.5}});
    }
  }
  double best = std::numeric_limits<double>::infinity();
  for (const auto& [a, b] : edges) best = std::min(best, segment_distance(p, a, b));
  best = std::min(best, std::abs((p - Eigen::Vector3d(0.6, 1.6, 0.2)).norm() - 0.2) + 0.0);
  if ((p - Eigen::Vector3d(0.6, 1.6, 0.2)).norm() < 0.25) best = 0.0;
  return best;
}

class KeypointTest : public ::testing::Test {
 protected:
  void SetUp() override {
    camera_ = camera::DepthCameraModel(testing::test_calibration(), 5000.0);
    T_world_cam_ = testing::look_at(Eigen::Vector3d(2.6, 2.4, 1.7), Eigen::Vector3d(0.9, 0.9, 0.3));
    depth_ = testing::render_depth(testing::room_corner(), testing::test_calibration(), T_world_cam_, 1.0e-3);
    ASSERT_EQ(preprocessor_.configure(camera_, config_, 16384), "");
    cloud_ = preprocessor_.make_cloud();
    ASSERT_EQ(preprocessor_.process(depth_, cloud_), GeometryStatus::kOk);
    ASSERT_EQ(detector_.configure(config_, 16384), "");
    keypoints_.assign(static_cast<std::size_t>(config_.max_keypoints), -1);
  }

  // Every keypoint lies where the large normal support reaches a crease or the sphere.
  void expect_near_structure(int count) const {
    const double leaf = static_cast<double>(cloud_.voxel_leaf_m);
    const double reach = config_.normal_radius_factor * leaf + 2.5 * leaf;
    int far = 0;
    for (int k = 0; k < count; ++k) {
      const Eigen::Vector3d p = T_world_cam_ * cloud_.points[static_cast<std::size_t>(keypoints_[static_cast<std::size_t>(k)])].cast<double>();
      far += distance_to_structure(p) > reach ? 1 : 0;
    }
    EXPECT_LE(far, count / 50) << far << " of " << count << " keypoints away from every crease";
  }

  camera::DepthCameraModel camera_;
  Eigen::Isometry3d T_world_cam_;
  cv::Mat depth_;
  GeometryConfig config_;
  CloudPreprocessor preprocessor_;
  SampledCloud cloud_;
  KeypointDetector detector_;
  std::vector<int> keypoints_;
};

TEST_F(KeypointTest, RosKeepsSalientPointsPastTheTransition) {
  for (const RosSelection selection : {RosSelection::kMostSalient, RosSelection::kFirstPastTransition}) {
    SCOPED_TRACE(to_string(selection));
    config_.ros_selection = selection;
    ASSERT_EQ(detector_.configure(config_, 16384), "");
    GeometryStatus status = GeometryStatus::kNotConfigured;
    const int count = detector_.detect(KeypointMethod::kRos, cloud_, keypoints_, status);
    ASSERT_EQ(status, GeometryStatus::kOk);
    const KeypointStats& stats = detector_.stats();
    EXPECT_GT(stats.transition, cloud_.size / 5);  // k* ≥ k0 = 20 %
    EXPECT_EQ(stats.candidates, cloud_.size - stats.transition);
    const int usable = stats.candidates - static_cast<int>(std::ceil(0.05 * stats.candidates));
    EXPECT_EQ(count, std::min(config_.max_keypoints, usable));
    // Past the transition, below the gross-error cut: the most salient downwards, or the first
    // values past the transition upwards.
    const auto saliency = detector_.saliency();
    std::vector<double> sorted(saliency.begin(), saliency.end());
    std::sort(sorted.begin(), sorted.end());
    for (int k = 0; k < count; ++k) {
      const int rank = selection == RosSelection::kMostSalient ? stats.transition + usable - 1 - k
                                                                : stats.transition + k;
      EXPECT_EQ(saliency[static_cast<std::size_t>(keypoints_[static_cast<std::size_t>(k)])],
                sorted[static_cast<std::size_t>(rank)])
          << k;
    }
    expect_near_structure(count);
  }
}

// θ_i against a brute-force search: the mean squared normal angle to the ros_neighbours nearest
// sampled points, on one thread and on a team.
TEST_F(KeypointTest, RosSaliencyIsTheMeanSquaredNormalAngleToTheNearestNeighbours) {
  const int n = cloud_.size;
  const int k = config_.ros_neighbours;
  std::vector<double> expected(static_cast<std::size_t>(n));
  std::vector<std::pair<float, int>> by_distance(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = cloud_.points[static_cast<std::size_t>(i)];
    for (int j = 0; j < n; ++j) {
      by_distance[static_cast<std::size_t>(j)] = {(cloud_.points[static_cast<std::size_t>(j)] - p).squaredNorm(), j};
    }
    by_distance[static_cast<std::size_t>(i)].first = std::numeric_limits<float>::infinity();
    std::partial_sort(by_distance.begin(), by_distance.begin() + k, by_distance.end());
    double sum = 0.0;
    for (int q = 0; q < k; ++q) {
      const Eigen::Vector3f& other = cloud_.normals[static_cast<std::size_t>(by_distance[static_cast<std::size_t>(q)].second)];
      const double angle = std::acos(std::clamp(static_cast<double>(cloud_.normals[static_cast<std::size_t>(i)].dot(other)), -1.0, 1.0));
      sum += angle * angle;
    }
    expected[static_cast<std::size_t>(i)] = sum / k;
  }
  parallel::ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  for (parallel::ThreadTeam* threads : {static_cast<parallel::ThreadTeam*>(nullptr), &team}) {
    KeypointDetector detector;
    ASSERT_EQ(detector.configure(config_, 16384, threads), "");
    GeometryStatus status = GeometryStatus::kNotConfigured;
    (void)detector.detect(KeypointMethod::kRos, cloud_, keypoints_, status);
    ASSERT_EQ(status, GeometryStatus::kOk);
    const auto saliency = detector.saliency();
    ASSERT_EQ(static_cast<int>(saliency.size()), n);
    for (int i = 0; i < n; ++i) {
      // The detector's arc cosine is a polynomial good to about 1e-7 rad.
      ASSERT_NEAR(saliency[static_cast<std::size_t>(i)], expected[static_cast<std::size_t>(i)],
                  1e-5 + 1e-4 * expected[static_cast<std::size_t>(i)])
          << "point " << i << (threads != nullptr ? ", team" : "");
    }
  }
}

TEST_F(KeypointTest, Is3dFindsTheRoomsThreeOrientationsAndKeepsTheRest) {
  GeometryStatus status = GeometryStatus::kNotConfigured;
  const int count = detector_.detect(KeypointMethod::kIs3d, cloud_, keypoints_, status);
  ASSERT_EQ(status, GeometryStatus::kOk);
  const KeypointStats& stats = detector_.stats();
  ASSERT_EQ(stats.orientations, 3);
  // Floor (+z) and walls (+x, +y) in the camera frame; the box faces share them.
  const Eigen::Matrix3d R_cam_world = T_world_cam_.linear().transpose();
  const std::array<Eigen::Vector3d, 3> axes = {Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0), Eigen::Vector3d(0, 0, 1)};
  for (const Eigen::Vector3d& axis : axes) {
    double best = -1.0;
    for (int o = 0; o < stats.orientations; ++o) best = std::max(best, stats.orientation[static_cast<std::size_t>(o)].dot(R_cam_world * axis));
    EXPECT_GT(best, std::cos(3.0 * M_PI / 180.0)) << "axis " << axis.transpose();
  }
  int grouped = 0;
  for (int o = 0; o < stats.orientations; ++o) grouped += stats.group_size[static_cast<std::size_t>(o)];
  EXPECT_EQ(grouped + stats.candidates, cloud_.size);
  EXPECT_GT(count, 50);
  EXPECT_LE(count, config_.max_keypoints);
  expect_near_structure(count);
}

// IS3D's grouping done beforehand (as the front-end does, beside the neighbour grids) gives the
// keypoints and statistics of the detection that groups by itself. It is used by the next
// detection only, and only by an IS3D detection of the same cloud.
TEST_F(KeypointTest, Is3dGroupingDoneBeforehandIsTheDetectionsOwn) {
  GeometryStatus status = GeometryStatus::kNotConfigured;
  const int count = detector_.detect(KeypointMethod::kIs3d, cloud_, keypoints_, status);
  ASSERT_EQ(status, GeometryStatus::kOk);
  const KeypointStats expected = detector_.stats();
  const std::vector<int> expected_keypoints(keypoints_.begin(), keypoints_.begin() + count);
  KeypointDetector detector;
  ASSERT_EQ(detector.configure(config_, 16384), "");
  const auto expect_as_alone = [&](const char* what) {
    std::fill(keypoints_.begin(), keypoints_.end(), -1);
    ASSERT_EQ(detector.detect(KeypointMethod::kIs3d, cloud_, keypoints_, status), count) << what;
    ASSERT_EQ(status, GeometryStatus::kOk) << what;
    const KeypointStats& stats = detector.stats();
    EXPECT_EQ(stats.orientations, expected.orientations) << what;
    EXPECT_EQ(stats.candidates, expected.candidates) << what;
    for (int o = 0; o < expected.orientations; ++o) {
      EXPECT_EQ(stats.orientation[static_cast<std::size_t>(o)], expected.orientation[static_cast<std::size_t>(o)]) << what;
      EXPECT_EQ(stats.group_size[static_cast<std::size_t>(o)], expected.group_size[static_cast<std::size_t>(o)]) << what;
    }
    EXPECT_TRUE(std::equal(expected_keypoints.begin(), expected_keypoints.end(), keypoints_.begin())) << what;
  };

  detector.prepare(KeypointMethod::kIs3d, cloud_);
  detector.group_orientations(cloud_);
  expect_as_alone("grouped beforehand");

  // A grouping of other normals, left unused, would give other keypoints.
  const std::vector<Eigen::Vector3f> normals = cloud_.normals;
  std::fill(cloud_.normals.begin(), cloud_.normals.end(), Eigen::Vector3f::UnitZ());
  detector.group_orientations(cloud_);
  cloud_.normals = normals;
  (void)detector.detect(KeypointMethod::kRos, cloud_, keypoints_, status);
  ASSERT_EQ(status, GeometryStatus::kOk);
  expect_as_alone("grouped, then a ROS detection");

  // Nor by a detection of another cloud.
  SampledCloud other = cloud_;
  std::fill(other.normals.begin(), other.normals.end(), Eigen::Vector3f::UnitZ());
  detector.group_orientations(other);
  expect_as_alone("grouped for another cloud");
}

TEST_F(KeypointTest, UniformSamplingSpreadsAboutMaxKeypoints) {
  GeometryStatus status = GeometryStatus::kNotConfigured;
  const int count = detector_.detect(KeypointMethod::kUniform, cloud_, keypoints_, status);
  ASSERT_EQ(status, GeometryStatus::kOk);
  EXPECT_LE(count, config_.max_keypoints);
  EXPECT_GE(count, config_.max_keypoints * 9 / 10);
  // One point per cell: no two closer than a fraction of the cell.
  const float cell = detector_.stats().uniform_cell_m;
  int close = 0;
  for (int a = 0; a < count; ++a) {
    for (int b = a + 1; b < count; ++b) {
      const float d = (cloud_.points[static_cast<std::size_t>(keypoints_[static_cast<std::size_t>(a)])] -
                       cloud_.points[static_cast<std::size_t>(keypoints_[static_cast<std::size_t>(b)])]).norm();
      close += d < 0.25F * cell ? 1 : 0;
    }
  }
  EXPECT_LE(close, count / 20);
}

TEST_F(KeypointTest, DetectionIsDeterministic) {
  for (const KeypointMethod method : {KeypointMethod::kIs3d, KeypointMethod::kRos, KeypointMethod::kUniform}) {
    GeometryStatus status = GeometryStatus::kNotConfigured;
    const int first = detector_.detect(method, cloud_, keypoints_, status);
    const std::vector<int> a(keypoints_.begin(), keypoints_.begin() + first);
    const int second = detector_.detect(method, cloud_, keypoints_, status);
    const std::vector<int> b(keypoints_.begin(), keypoints_.begin() + second);
    EXPECT_EQ(a, b) << to_string(method);
  }
}

TEST_F(KeypointTest, CapacityAndInputErrors) {
  GeometryStatus status = GeometryStatus::kOk;
  std::vector<int> small(10);
  EXPECT_EQ(detector_.detect(KeypointMethod::kRos, cloud_, small, status), 0);
  EXPECT_EQ(status, GeometryStatus::kCapacityExceeded);
  SampledCloud empty = preprocessor_.make_cloud();
  EXPECT_EQ(detector_.detect(KeypointMethod::kIs3d, empty, keypoints_, status), 0);
  EXPECT_EQ(status, GeometryStatus::kTooFewPoints);
  KeypointDetector unconfigured;
  EXPECT_EQ(unconfigured.detect(KeypointMethod::kIs3d, cloud_, keypoints_, status), 0);
  EXPECT_EQ(status, GeometryStatus::kNotConfigured);
}

}  // namespace
}  // namespace rankslam::geometry
