#include "rankslam/slam/point_map.hpp"

#include <gtest/gtest.h>

#include <cstring>

namespace rankslam::slam {
namespace {

TEST(PointMap, MergesPointsOfOneVoxelIntoTheirMean) {
  PointMap map(0.1, 100);
  map.insert({0.01F, 0.01F, 0.01F}, 10, 20, 30);
  map.insert({0.03F, 0.05F, 0.07F}, 30, 40, 50);
  map.insert({0.51F, 0.0F, 0.0F}, 0, 0, 0);
  EXPECT_EQ(map.size(), 2U);
  const std::string ply = map.to_ply();
  const auto header_end = ply.find("end_header\n");
  ASSERT_NE(header_end, std::string::npos);
  EXPECT_NE(ply.find("element vertex 2"), std::string::npos);
  EXPECT_EQ(ply.size(), header_end + 11 + 2 * 15);
  // Find the merged vertex and check its mean position and colour (PLY stores RGB).
  bool found = false;
  for (std::size_t offset = header_end + 11; offset < ply.size(); offset += 15) {
    float xyz[3];
    std::memcpy(xyz, &ply[offset], sizeof xyz);
    if (xyz[0] < 0.1F) {
      found = true;
      EXPECT_NEAR(xyz[0], 0.02F, 1e-6F);
      EXPECT_NEAR(xyz[1], 0.03F, 1e-6F);
      EXPECT_NEAR(xyz[2], 0.04F, 1e-6F);
      EXPECT_EQ(static_cast<unsigned char>(ply[offset + 12]), 40);  // red
      EXPECT_EQ(static_cast<unsigned char>(ply[offset + 14]), 20);  // blue
    }
  }
  EXPECT_TRUE(found);
}

TEST(PointMap, NeverGrowsPastCapacity) {
  PointMap map(0.01, 50);
  for (int i = 0; i < 200; ++i) map.insert({static_cast<float>(i) * 0.05F, 0.0F, 0.0F}, 1, 2, 3);
  EXPECT_EQ(map.size(), 50U);
  EXPECT_EQ(map.rejected_points(), 150U);
  // Points in voxels already held still merge.
  map.insert({0.0F, 0.0F, 0.0F}, 1, 2, 3);
  EXPECT_EQ(map.rejected_points(), 150U);
}

TEST(PointMap, AFullMapFindsEveryVoxelItHoldsAndClearsToEmpty) {
  PointMap map(0.02, 1000);
  const auto point = [](int i) {
    return Eigen::Vector3f(static_cast<float>(i % 10) * 0.02F + 0.01F, static_cast<float>((i / 10) % 10) * 0.02F + 0.01F,
                           static_cast<float>(i / 100) * 0.02F + 0.01F);
  };
  for (int i = 0; i < 1000; ++i) map.insert(point(i), 0, 0, static_cast<std::uint8_t>(i % 200));
  EXPECT_EQ(map.size(), 1000U);
  // Full, every voxel is still found: a second pass merges into them, nothing is rejected.
  for (int i = 0; i < 1000; ++i) map.insert(point(i), 0, 0, static_cast<std::uint8_t>(i % 200));
  EXPECT_EQ(map.size(), 1000U);
  EXPECT_EQ(map.rejected_points(), 0U);
  map.insert({5.0F, 5.0F, 5.0F}, 0, 0, 0);
  EXPECT_EQ(map.rejected_points(), 1U);
  map.clear();
  EXPECT_EQ(map.size(), 0U);
  EXPECT_EQ(map.rejected_points(), 0U);
  map.insert(point(7), 1, 2, 3);
  EXPECT_EQ(map.size(), 1U);
  EXPECT_NE(map.to_ply().find("element vertex 1\n"), std::string::npos);
}

TEST(PointMap, IgnoresNonFinitePoints) {
  PointMap map(0.1, 10);
  map.insert({std::numeric_limits<float>::quiet_NaN(), 0.0F, 0.0F}, 0, 0, 0);
  map.insert({std::numeric_limits<float>::infinity(), 0.0F, 0.0F}, 0, 0, 0);
  EXPECT_EQ(map.size(), 0U);
}

}  // namespace
}  // namespace rankslam::slam
