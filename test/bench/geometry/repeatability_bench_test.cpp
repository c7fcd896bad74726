// Keypoint repeatability orderings (thesis Fig. 4.7 and 5.7): on simulated pairs misaligned by 0,
// 5, 15 and 20°, IS3D ≥ ROS ≥ uniform sampling, and IS3D ≥ PCL's ISS everywhere. The full
// table (also real fr1 pairs) is printed; the repeatability tool prints the same.

#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "repeatability.hpp"

namespace rankslam::geometry::bench {
namespace {

const std::vector<RepeatabilityRow>& table() {
  static const std::vector<RepeatabilityRow> rows = [] {
    RepeatabilityOptions options;
    options.pairs_per_angle = 10;
    std::vector<RepeatabilityRow> out;
    const std::string error = run_repeatability(options, out);
    EXPECT_EQ(error, "");
    std::fputs(format_repeatability_table(out).c_str(), stdout);
    return out;
  }();
  return rows;
}

double value(const RepeatabilityRow& row, int method) {
  return row.repeatability[static_cast<std::size_t>(method)];
}

// The full ordering on both simulated scenes. ROS keeps the most salient of its group 2
// (RosSelection::kMostSalient) after the thesis' 5 % gross-error cut; IS3D keeps the most salient
// of the points in no dominant orientation group, with no cut (is3d_gross_error_fraction). Measured
// with 10 pairs per angle at 0/5/15/20° (the tool prints these tables; paired leads are mean ±
// standard error over the pairs, percentage points):
//   sim office:  IS3D 98.0/96.9/94.2/92.3 %, ROS 96.9/94.6/92.0/90.7 %, uniform 87.7/53.5/53.4/55.5 %;
//                IS3D − ROS +1.1±0.5/+2.3±0.6/+2.3±1.1/+1.6±1.1 (20 pairs: +1.1±0.3/+1.7±0.5/
//                +1.9±0.6/+1.6±0.6).
//   sim zig-zag: IS3D 99.8/97.8/99.8/99.9 %, ROS 98.9/97.7/98.0/98.8 %, uniform 85.9/65.4/54.3/52.1 %;
//                IS3D − ROS +0.8±0.3/+0.1±0.5/+1.8±0.3/+1.1±0.2 (20 pairs: +0.9±0.2/+0.3±0.3/
//                +1.3±0.3/+1.0±0.2): at 5° the two are level within the noise.
// ROS − uniform leads by 8 to 47 points and IS3D − ISS by 54 to 74 on every simulated row; on the
// real fr1 pairs IS3D and ROS are level (−1.3 to +1.3 points, within their standard errors). Before
// (ROS taking the first values past its transition, as the thesis words it, and IS3D dropping
// the top 5 % of its candidates): office IS3D 96.7/93.6/90.4/89.3, ROS 93.3/88.0/85.9/84.7 %;
// zig-zag IS3D 99.3/98.0/99.3/99.6, ROS 60.2/48.8/44.1/42.6 %, below uniform. Without any cut
// for either, the two select nearly the same points and tie (office IS3D 98.0/96.9/94.2/92.3,
// ROS 97.9/96.5/93.9/92.1 %): IS3D's lead here is the cut ROS keeps from the thesis.
void check_ordering(const std::vector<RepeatabilityRow>& rows, const std::string& set) {
  int checked = 0;
  for (const RepeatabilityRow& row : rows) {
    if (row.set != set) continue;
    ++checked;
    ASSERT_GT(row.pairs, 0) << set << " " << row.misalignment_deg;
    EXPECT_GE(value(row, kMethodIs3d), value(row, kMethodRos)) << set << " " << row.misalignment_deg << "°";
    EXPECT_GE(value(row, kMethodRos), value(row, kMethodUniform)) << set << " " << row.misalignment_deg << "°";
  }
  EXPECT_EQ(checked, 4) << set;
}

void check_iss(const std::vector<RepeatabilityRow>& rows) {
  for (const RepeatabilityRow& row : rows) {
    if (row.set.rfind("sim ", 0) != 0) continue;
    EXPECT_GE(value(row, kMethodIs3d), value(row, kMethodIss)) << row.set << " " << row.misalignment_deg << "°";
  }
}

// One test: ctest runs each test in a process of its own, and the table takes over a minute.
TEST(Repeatability, OrderingsOnSimulatedPairs) {
  const std::vector<RepeatabilityRow>& rows = table();
  check_ordering(rows, "sim office");
  check_ordering(rows, "sim zigzag-plain");
  if (have_iss()) {
    check_iss(rows);
  } else {
    std::printf("built without PCL: no ISS oracle\n");
  }
}

}  // namespace
}  // namespace rankslam::geometry::bench
