#include "rankslam/slam/keyframe_store.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace rankslam::slam {
namespace {

Eigen::Isometry3d at(double x_m) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation().x() = x_m;
  return pose;
}

// Fills every slot with key-frames 1 m apart along x, in creation order.
void fill(KeyframeStore& store) {
  for (int i = 0; i < store.capacity(); ++i) {
    const int slot = store.free_slot();
    ASSERT_EQ(slot, i);
    store.occupy(slot);
    store.slot(slot).sequence = i + 1;
    store.slot(slot).T_world_cam = at(i);
  }
}

TEST(KeyframeStore, FillsFreeSlotsThenReportsFull) {
  KeyframeStore store(4, 10, 5, 0, 20);
  EXPECT_EQ(store.size(), 0);
  fill(store);
  EXPECT_EQ(store.size(), 4);
  EXPECT_EQ(store.free_slot(), -1);
  store.release(2);
  EXPECT_EQ(store.size(), 3);
  EXPECT_EQ(store.free_slot(), 2);
}

TEST(KeyframeStore, RetiresTheOldestUnconnectedKeyframeAwayFromTheCamera) {
  KeyframeStore store(6, 10, 5, 0, 20);
  fill(store);
  // Slot 0 holds a loop closure: kept while unconnected ones remain.
  store.slot(0).loop_closures = 1;
  // Camera at x = 5; key-frames within 1.5 m (slots 4, 5) and the 2 most recent are protected.
  EXPECT_EQ(store.retirement_candidate(at(5.0), 1.5, 2), 1);
  store.slot(1).loop_closures = 2;
  store.slot(2).loop_closures = 1;
  store.slot(3).loop_closures = 1;
  // Now every candidate has closures: the fewest, then the oldest.
  EXPECT_EQ(store.retirement_candidate(at(5.0), 1.5, 2), 0);
  // All within reach of the camera: nothing may go.
  EXPECT_EQ(store.retirement_candidate(at(2.5), 10.0, 2), -1);
}

TEST(KeyframeStore, CopiesFeaturesIntoTheSlotsPreallocatedMemory) {
  PhotometricFeatures from;
  from.reserve(8);
  for (int i = 0; i < 3; ++i) {
    from.keypoints.emplace_back(static_cast<float>(i), 1.0F, 31.0F);
    from.points_cam.emplace_back(static_cast<float>(i), 0.0F, 1.0F);
    from.sigma_m.push_back(0.01F * static_cast<float>(i + 1));
  }
  for (int i = 0; i < 3; ++i) from.descriptor_storage.row(i).setTo(i + 7);
  from.descriptors = from.descriptor_storage.rowRange(0, 3);
  from.source = ImageSource::kInfrared;

  KeyframeStore store(1, 8, 4, 3, 10);
  PhotometricFeatures& to = store.slot(0).photometric;
  const unsigned char* memory = to.descriptor_storage.data;
  KeyframeStore::copy_features(from, to);
  ASSERT_EQ(to.size(), 3U);
  EXPECT_EQ(to.descriptor_storage.data, memory);
  EXPECT_EQ(to.descriptors.rows, 3);
  EXPECT_EQ(to.descriptors.at<unsigned char>(2, 31), 9);
  EXPECT_FLOAT_EQ(to.sigma_m[1], 0.02F);
  EXPECT_EQ(to.source, ImageSource::kInfrared);

  geometry::GeometricFeatures geometric;
  geometric.reserve(6, 7, 0);
  geometric.count = 6;
  geometric.descriptors[5 * geometry::kShotSize] = 0.5F;
  geometric.voxel_leaf_m = 0.03F;
  geometric.cloud_count = 7;
  for (int i = 0; i < 7; ++i) {
    const auto k = static_cast<std::size_t>(i);
    geometric.cloud_points[k] = Eigen::Vector3f(static_cast<float>(i), 0.0F, 1.0F);
    geometric.cloud_normals[k] = Eigen::Vector3f(0.0F, 0.0F, -1.0F);
    geometric.cloud_pixels[k] = Eigen::Vector2f(static_cast<float>(10 * i), 5.0F);
    geometric.cloud_curvature[k] = 0.001F * static_cast<float>(i);
  }
  StoredGeometry& stored = store.slot(0).geometric;
  KeyframeStore::copy_features(geometric, stored);
  EXPECT_EQ(stored.count, 4);  // capped at the slot's capacity
  EXPECT_FLOAT_EQ(stored.voxel_leaf_m, 0.03F);
  // 7 cloud points into room for 3: every third, in order, each with its own normal and pixel.
  ASSERT_EQ(stored.cloud_count, 3);
  for (int i = 0; i < 3; ++i) {
    const auto k = static_cast<std::size_t>(i);
    EXPECT_FLOAT_EQ(stored.cloud_points[k].x(), static_cast<float>(3 * i));
    EXPECT_FLOAT_EQ(stored.cloud_pixels[k].x(), static_cast<float>(30 * i));
    EXPECT_FLOAT_EQ(stored.cloud_curvature[k], 0.003F * static_cast<float>(i));
    EXPECT_FLOAT_EQ(StoredGeometry::decode_normal(stored.cloud_normals[k]).z(), -1.0F);
  }
}

// SHOT-like descriptors (non-negative, unit norm, many empty bins) through the store's codes.
TEST(StoredGeometry, ShotCodesKeepEveryValueWithinHalfAStepAndReencodeToThemselves) {
  std::mt19937 random(11);
  std::uniform_real_distribution<float> uniform(0.0F, 1.0F);
  std::vector<float> values(geometry::kShotSize);
  std::vector<float> decoded(geometry::kShotSize);
  std::vector<std::uint8_t> codes(geometry::kShotSize);
  std::vector<std::uint8_t> again(geometry::kShotSize);
  for (int trial = 0; trial < 2000; ++trial) {
    float norm = 0.0F;
    for (float& value : values) {
      value = uniform(random) < 0.6F ? 0.0F : std::pow(uniform(random), 3.0F);
      norm += value * value;
    }
    if (norm == 0.0F) continue;
    for (float& value : values) value /= std::sqrt(norm);
    const float scale = StoredGeometry::encode(values.data(), codes.data());
    ASSERT_GT(scale, 0.0F);
    StoredGeometry::decode(codes.data(), scale, decoded.data());
    float largest = 0.0F;
    for (int d = 0; d < geometry::kShotSize; ++d) {
      const auto k = static_cast<std::size_t>(d);
      largest = std::max(largest, values[k]);
      ASSERT_LE(std::abs(decoded[k] - values[k]), 0.5F * scale * 1.0001F) << "trial " << trial << ", value " << d;
    }
    EXPECT_LE(scale, largest / 255.0F * 1.0001F);
    // A map saved, loaded and saved again writes the same codes and scale.
    ASSERT_EQ(StoredGeometry::encode(decoded.data(), again.data()), scale) << "trial " << trial;
    ASSERT_EQ(again, codes) << "trial " << trial;
  }
  // What is not a positive finite value codes as 0; nothing positive gives scale 0.
  std::fill(values.begin(), values.end(), 0.0F);
  values[0] = -1.0F;
  values[1] = std::numeric_limits<float>::quiet_NaN();
  values[2] = std::numeric_limits<float>::infinity();
  EXPECT_EQ(StoredGeometry::encode(values.data(), codes.data()), 0.0F);
  EXPECT_EQ(std::count(codes.begin(), codes.end(), 0), geometry::kShotSize);
  values[3] = 0.5F;
  const float scale = StoredGeometry::encode(values.data(), codes.data());
  EXPECT_EQ(codes[3], 255);
  EXPECT_EQ(codes[0] + codes[1] + codes[2], 0);
  EXPECT_FLOAT_EQ(255.0F * scale, 0.5F);
}

TEST(StoredGeometry, NormalCodesKeepEachComponentWithinHalfAStep) {
  std::mt19937 random(5);
  std::normal_distribution<float> gauss(0.0F, 1.0F);
  for (int trial = 0; trial < 10000; ++trial) {
    const Eigen::Vector3f normal = Eigen::Vector3f(gauss(random), gauss(random), gauss(random)).normalized();
    const auto codes = StoredGeometry::encode_normal(normal);
    const Eigen::Vector3f back = StoredGeometry::decode_normal(codes);
    ASSERT_LE((back - normal).cwiseAbs().maxCoeff(), 0.5F / 32767.0F * 1.001F) << "trial " << trial;
    ASSERT_EQ(StoredGeometry::encode_normal(back), codes) << "trial " << trial;
  }
  const Eigen::Vector3f odd(std::numeric_limits<float>::quiet_NaN(), 2.0F, -std::numeric_limits<float>::infinity());
  const auto codes = StoredGeometry::encode_normal(odd);
  EXPECT_EQ(codes[0], 0);
  EXPECT_EQ(codes[1], 32767);
  EXPECT_EQ(codes[2], 0);
}

TEST(AdaptiveLoopThreshold, StartsAtTheInitialValueThenFollowsMeanMinusDeviation) {
  AdaptiveLoopThreshold threshold(60.0, 1.0);
  EXPECT_DOUBLE_EQ(threshold.value(), 60.0);
  threshold.add(100, 40);
  EXPECT_DOUBLE_EQ(threshold.value(), 60.0);  // one closure is not a distribution
  threshold.add(200, 60);
  // Photometric 150 ± 50, geometric 50 ± 10: (150 - 50) + (50 - 10).
  EXPECT_NEAR(threshold.value(), 140.0, 1e-9);
  AdaptiveLoopThreshold strict(60.0, 0.0);
  strict.add(100, 40);
  strict.add(200, 60);
  EXPECT_NEAR(strict.value(), 200.0, 1e-9);
}

TEST(AdaptiveLoopThreshold, AFixedOneKeepsTheInitialValueWhateverTheClosures) {
  AdaptiveLoopThreshold fixed(100.0, 1.0, /*adaptive=*/false);
  fixed.add(100, 40);
  fixed.add(200, 60);
  fixed.add(300, 80);
  EXPECT_DOUBLE_EQ(fixed.value(), 100.0);
  EXPECT_EQ(fixed.count(), 3);  // the statistics are still kept (and saved with the map)
}

}  // namespace
}  // namespace rankslam::slam
