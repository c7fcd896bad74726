#include "rankslam/slam/point_map.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

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

// The vertices of a PLY as (x, y, z, r, g, b) rows, sorted.
std::vector<std::array<float, 6>> vertices(const std::string& ply) {
  std::vector<std::array<float, 6>> out;
  for (std::size_t offset = ply.find("end_header\n") + 11; offset + 15 <= ply.size(); offset += 15) {
    std::array<float, 6> row{};
    std::memcpy(row.data(), &ply[offset], 3 * sizeof(float));
    for (int c = 0; c < 3; ++c) row[3 + c] = static_cast<unsigned char>(ply[offset + 12 + c]);
    out.push_back(row);
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(PointMap, TakingOutPointsLeavesTheMapOfTheRest) {
  // Three sets of points over one small region, so that they share voxels and the table's
  // probe runs; the map after taking out the middle set, point by point in another order, must
  // be the map of the other two.
  std::mt19937 random(7);
  std::uniform_real_distribution<float> coordinate(0.0F, 0.3F);
  std::uniform_int_distribution<int> level(0, 255);
  struct Point {
    Eigen::Vector3f position;
    std::uint8_t b, g, r;
  };
  std::array<std::vector<Point>, 3> sets;
  for (auto& set : sets) {
    for (int i = 0; i < 3000; ++i) {
      set.push_back({{coordinate(random), coordinate(random), coordinate(random)}, static_cast<std::uint8_t>(level(random)),
                     static_cast<std::uint8_t>(level(random)), static_cast<std::uint8_t>(level(random))});
    }
  }
  PointMap all(0.02, 4000);
  PointMap rest(0.02, 4000);
  for (int s = 0; s < 3; ++s) {
    for (const Point& p : sets[static_cast<std::size_t>(s)]) {
      ASSERT_TRUE(all.insert(p.position, p.b, p.g, p.r));
      if (s != 1) {
        ASSERT_TRUE(rest.insert(p.position, p.b, p.g, p.r));
      }
    }
  }
  ASSERT_GT(all.size(), rest.size());
  std::vector<Point> middle = sets[1];
  std::shuffle(middle.begin(), middle.end(), random);
  for (const Point& p : middle) ASSERT_TRUE(all.remove(p.position, p.b, p.g, p.r));
  EXPECT_EQ(all.size(), rest.size());
  EXPECT_EQ(all.points(), 6000U);
  const auto got = vertices(all.to_ply());
  const auto want = vertices(rest.to_ply());
  ASSERT_EQ(got.size(), want.size());
  // Each vertex has its twin (the means differ by rounding only; the colours not at all).
  std::vector<bool> taken(want.size(), false);
  int unmatched = 0;
  for (const auto& row : got) {
    bool found = false;
    for (std::size_t j = 0; j < want.size() && !found; ++j) {
      if (taken[j]) continue;
      bool same = true;
      for (std::size_t c = 0; c < 6 && same; ++c) same = std::abs(row[c] - want[j][c]) <= (c < 3 ? 1e-5F : 0.0F);
      if (same) found = taken[j] = true;
    }
    unmatched += found ? 0 : 1;
  }
  EXPECT_EQ(unmatched, 0);
  // Every voxel is still found after the shifts: taking out the rest empties the map, and its
  // room is free again.
  for (const std::size_t s : {0U, 2U}) {
    for (const Point& p : sets[s]) ASSERT_TRUE(all.remove(p.position, p.b, p.g, p.r));
  }
  EXPECT_EQ(all.size(), 0U);
  EXPECT_EQ(all.points(), 0U);
  EXPECT_FALSE(all.remove(sets[0][0].position, 0, 0, 0));
  for (const Point& p : sets[1]) ASSERT_TRUE(all.insert(p.position, p.b, p.g, p.r));
  EXPECT_EQ(all.rejected_points(), 0U);
}

TEST(PointMap, IgnoresNonFinitePoints) {
  PointMap map(0.1, 10);
  map.insert({std::numeric_limits<float>::quiet_NaN(), 0.0F, 0.0F}, 0, 0, 0);
  map.insert({std::numeric_limits<float>::infinity(), 0.0F, 0.0F}, 0, 0, 0);
  EXPECT_EQ(map.size(), 0U);
}

}  // namespace
}  // namespace rankslam::slam
