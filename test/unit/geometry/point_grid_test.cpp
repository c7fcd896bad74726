#include <algorithm>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/geometry/point_grid.hpp"

namespace rankslam::geometry {
namespace {

std::vector<Eigen::Vector3f> random_points(int n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.0F, 1.0F);
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < n; ++i) {
    // A surface-like cloud: a wavy sheet plus a few scattered points.
    const float x = u(rng);
    const float y = u(rng);
    const float z = i % 10 == 0 ? u(rng) : 0.2F * std::sin(3.0F * x) + 0.01F * u(rng);
    points.emplace_back(x, y, 2.0F + z);
  }
  return points;
}

TEST(PointGrid, NearestMatchesBruteForce) {
  const auto points = random_points(3000, 1);
  PointGrid grid(3000);
  ASSERT_TRUE(grid.build(points, 0.05F));
  std::mt19937 rng(2);
  std::uniform_int_distribution<int> pick(0, 2999);
  for (int trial = 0; trial < 200; ++trial) {
    const int q = pick(rng);
    std::array<int, 10> idx{};
    std::array<float, 10> d2{};
    const int found = grid.nearest(points[static_cast<std::size_t>(q)], 10, q, 40, idx.data(), d2.data());
    ASSERT_EQ(found, 10);
    std::vector<std::pair<float, int>> all;
    for (int i = 0; i < 3000; ++i) {
      if (i == q) continue;
      all.emplace_back((points[static_cast<std::size_t>(i)] - points[static_cast<std::size_t>(q)]).squaredNorm(), i);
    }
    std::partial_sort(all.begin(), all.begin() + 10, all.end());
    for (int k = 0; k < 10; ++k) {
      EXPECT_FLOAT_EQ(d2[static_cast<std::size_t>(k)], all[static_cast<std::size_t>(k)].first) << "trial " << trial;
    }
  }
}

TEST(PointGrid, RadiusQueryMatchesBruteForce) {
  const auto points = random_points(2000, 3);
  PointGrid grid(2000);
  ASSERT_TRUE(grid.build(points, 0.1F));
  for (int q = 0; q < 2000; q += 37) {
    std::vector<int> found;
    const Eigen::Vector3f& centre = points[static_cast<std::size_t>(q)];
    std::vector<int> visit_order;
    grid.for_each_in_radius(centre, 0.15F, [&](int i, float d2) {
      EXPECT_LE(d2, 0.15F * 0.15F);
#ifdef __FP_FAST_FMAF
      // The compiler fuses multiply-adds here (arm64), in the grid's sum and Eigen's alike but
      // not necessarily at the same step: they may round an ulp apart.
      EXPECT_FLOAT_EQ(d2, (points[static_cast<std::size_t>(i)] - centre).squaredNorm());
#else
      // Exactly the squared norm, vector path or not (descriptors built from it must not depend
      // on the CPU).
      EXPECT_EQ(d2, (points[static_cast<std::size_t>(i)] - centre).squaredNorm());
#endif
      found.push_back(i);
    });
    // Cell by cell, in sorted order within each cell, as the grid lists them.
    for (const PointGrid::Cell& cell : grid.cells()) {
      for (int k = cell.start; k < cell.start + cell.count; ++k) {
        const int i = grid.sorted_indices()[static_cast<std::size_t>(k)];
        if (std::find(found.begin(), found.end(), i) != found.end()) visit_order.push_back(i);
      }
    }
    std::vector<int> expected;
    for (int i = 0; i < 2000; ++i) {
      if ((points[static_cast<std::size_t>(i)] - points[static_cast<std::size_t>(q)]).squaredNorm() <= 0.15F * 0.15F) {
        expected.push_back(i);
      }
    }
    std::vector<int> found_by_cell = found;
    std::sort(found.begin(), found.end());
    EXPECT_EQ(found, expected);
    // Within each cell, the visits keep the sorted order.
    std::vector<int> cell_of(2000, -1);
    for (std::size_t c = 0; c < grid.cells().size(); ++c) {
      const PointGrid::Cell& cell = grid.cells()[c];
      for (int k = cell.start; k < cell.start + cell.count; ++k) {
        cell_of[static_cast<std::size_t>(grid.sorted_indices()[static_cast<std::size_t>(k)])] = static_cast<int>(c);
      }
    }
    std::vector<int> position(2000, -1);
    for (std::size_t k = 0; k < visit_order.size(); ++k) position[static_cast<std::size_t>(visit_order[k])] = static_cast<int>(k);
    for (std::size_t k = 1; k < found_by_cell.size(); ++k) {
      const int a = found_by_cell[k - 1];
      const int b = found_by_cell[k];
      if (cell_of[static_cast<std::size_t>(a)] == cell_of[static_cast<std::size_t>(b)]) {
        EXPECT_LT(position[static_cast<std::size_t>(a)], position[static_cast<std::size_t>(b)]);
      }
    }
  }
}

TEST(PointGrid, GatherInRadiusWritesTheRadiusQueryOffsetsInItsOrder) {
  auto points = random_points(2000, 5);
  // Copies of some query points: at distance 0 from their query, so counted but not written.
  for (int q = 0; q < 2000; q += 111) points.push_back(points[static_cast<std::size_t>(q)]);
  const int n = static_cast<int>(points.size());
  PointGrid grid(n);
  ASSERT_TRUE(grid.build(points, 0.1F));
  for (const int capacity : {n, 37, 5, 0}) {
    // Blocks of 8 are stored whole: room for capacity + 8, the rest must stay untouched.
    constexpr float kUntouched = -7.0F;
    const auto room = static_cast<std::size_t>(n + 8);
    std::vector<float> dx(room, kUntouched), dy(room, kUntouched), dz(room, kUntouched), d2(room, kUntouched);
    std::vector<int> index(room, -1);
    const PointGrid::RadiusGather out{dx.data(), dy.data(), dz.data(), d2.data(), index.data(), capacity};
    for (int q = 0; q < 2000; q += 37) {
      const Eigen::Vector3f& centre = points[static_cast<std::size_t>(q)];
      std::vector<int> expected;
      int expected_support = 0;
      grid.for_each_in_radius(centre, 0.15F, [&](int i, float distance2) {
        ++expected_support;
        if (distance2 != 0.0F) expected.push_back(i);
      });
      int written = -1;
      const int support = grid.gather_in_radius(centre, 0.15F, out, written);
      EXPECT_EQ(support, expected_support) << "query " << q;
      ASSERT_EQ(written, std::min(capacity, static_cast<int>(expected.size()))) << "query " << q;
      for (int k = 0; k < written; ++k) {
        const auto w = static_cast<std::size_t>(k);
        ASSERT_EQ(index[w], expected[w]) << "query " << q << " entry " << k;
        const Eigen::Vector3f offset = points[static_cast<std::size_t>(index[w])] - centre;
        EXPECT_EQ(dx[w], offset.x());
        EXPECT_EQ(dy[w], offset.y());
        EXPECT_EQ(dz[w], offset.z());
        EXPECT_EQ(d2[w], dx[w] * dx[w] + (dy[w] * dy[w] + dz[w] * dz[w]));
      }
      for (std::size_t k = static_cast<std::size_t>(capacity) + 8; k < room; ++k) {
        ASSERT_EQ(dx[k], kUntouched) << "written past capacity + 8 at " << k;
        ASSERT_EQ(index[k], -1);
      }
    }
  }
}

TEST(PointGrid, RejectsOverCapacityAndBadCells) {
  const auto points = random_points(100, 4);
  PointGrid grid(50);
  EXPECT_FALSE(grid.build(points, 0.1F));
  PointGrid roomy(100);
  EXPECT_FALSE(roomy.build(points, 0.0F));
  EXPECT_FALSE(roomy.build(points, std::numeric_limits<float>::quiet_NaN()));
  EXPECT_TRUE(roomy.build(points, 0.1F));
  EXPECT_EQ(static_cast<int>(roomy.sorted_indices().size()), 100);
}

TEST(PointGrid, FloorToIntIsFloorAndClamps) {
  EXPECT_EQ(floor_to_int(1.5F), 1);
  EXPECT_EQ(floor_to_int(-1.5F), -2);
  EXPECT_EQ(floor_to_int(-2.0F), -2);
  EXPECT_EQ(floor_to_int(std::numeric_limits<float>::quiet_NaN()), -1073741824);
  EXPECT_EQ(floor_to_int(1e30F), 1073741824);
}

}  // namespace
}  // namespace rankslam::geometry
