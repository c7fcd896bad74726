#include <limits>
#include <set>
#include <string>
#include <type_traits>

#include <gtest/gtest.h>

#include "rankslam/geometry/config.hpp"

namespace rankslam::geometry {
namespace {

TEST(GeometryConfig, DefaultsAreValidAndInsideTheirDeclaredRanges) {
  GeometryConfig config;
  EXPECT_EQ(config.validate(), "");
  std::set<std::string> names;
  int count = 0;
  config.visit_parameters([&](std::string_view name, auto& field, auto min, auto max,
                              std::string_view /*unit*/, std::string_view doc) {
    ++count;
    EXPECT_TRUE(names.insert(std::string(name)).second) << "duplicate parameter " << name;
    EXPECT_FALSE(doc.empty()) << name << " has no description";
    EXPECT_LE(static_cast<double>(min), static_cast<double>(field)) << name;
    EXPECT_GE(static_cast<double>(max), static_cast<double>(field)) << name;
  });
  EXPECT_GE(count, 30);
}

TEST(GeometryConfig, ThesisDefaults) {
  const GeometryConfig config;
  EXPECT_DOUBLE_EQ(config.max_depth_m, 4.0);        // §4.4.1 pass-through
  EXPECT_DOUBLE_EQ(config.voxel_leaf_factor, 11.0); // eq. 4.5, C = 11
  EXPECT_EQ(config.max_keypoints, 400);             // §4.3.3, §5.3.5
  EXPECT_DOUBLE_EQ(config.ros_min_inlier_fraction, 0.2);
  EXPECT_DOUBLE_EQ(config.gross_error_fraction, 0.05);
  EXPECT_EQ(config.msse_hypotheses, 1000);
}

TEST(GeometryConfig, ValidateNamesEachOutOfRangeField) {
  // Every numeric field pushed past its maximum (below its minimum where the maximum is the
  // type's largest value) is reported by its own name.
  GeometryConfig probe;
  std::vector<std::string> names;
  probe.visit_parameters([&](std::string_view name, auto&, auto, auto, std::string_view,
                             std::string_view) { names.emplace_back(name); });
  for (const std::string& target : names) {
    GeometryConfig config;
    config.visit_parameters([&](std::string_view name, auto& field, auto min, auto max,
                                std::string_view, std::string_view) {
      if (name != target) return;
      using Field = std::remove_reference_t<decltype(field)>;
      if constexpr (std::is_integral_v<Field>) {
        field = max < std::numeric_limits<Field>::max() ? static_cast<Field>(max + 1) : static_cast<Field>(min - 1);
      } else {
        field = static_cast<Field>(max + 1);
      }
    });
    EXPECT_EQ(config.validate(), target);
  }
}

TEST(GeometryConfig, ValidateChecksConsistency) {
  GeometryConfig config;
  config.min_depth_m = 5.0;
  config.max_depth_m = 4.0;
  EXPECT_EQ(config.validate(), "min_depth_m");
  config = GeometryConfig{};
  config.min_voxel_leaf_m = 0.3;
  config.max_voxel_leaf_m = 0.2;
  EXPECT_EQ(config.validate(), "min_voxel_leaf_m");
  config = GeometryConfig{};
  config.max_depth_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(config.validate(), "max_depth_m");
}

TEST(GeometryConfig, IcpDepthLimitIsThePassThroughLessItsMarginInDepthNoise) {
  GeometryConfig config;
  // 4 m less 2 σ at 4 m (σ = 1.425e-3 · 16 = 22.8 mm).
  EXPECT_NEAR(config.icp_depth_limit_m(1.425e-3), 4.0 - 2.0 * 0.0228, 1e-9);
  config.icp_pass_through_margin_sigmas = 0.0;
  EXPECT_DOUBLE_EQ(config.icp_depth_limit_m(1.425e-3), config.max_depth_m);
}

}  // namespace
}  // namespace rankslam::geometry
