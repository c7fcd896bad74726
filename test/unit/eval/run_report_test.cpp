#include "rankslam/eval/run_report.hpp"

#include <gtest/gtest.h>

namespace rankslam::eval {
namespace {

TEST(RunReport, StatusCountsFollowWhatThePoseConsumerSees) {
  StatusCounts counts;
  slam::FrameResult result;
  for (const auto status : {slam::FrameStatus::kFirstFrame, slam::FrameStatus::kTracking, slam::FrameStatus::kWheels,
                            slam::FrameStatus::kFailed, slam::FrameStatus::kFailed}) {
    result.status = status;
    counts.add(result);
  }
  EXPECT_EQ(counts.tracking, 2);
  EXPECT_EQ(counts.degraded, 1);
  EXPECT_EQ(counts.lost, 2);
}

TEST(RunReport, PercentilesTakeTheNearestRank) {
  const Percentiles p = percentiles({5.0, 1.0, 4.0, 2.0, 3.0, 10.0, 6.0, 7.0, 8.0, 9.0, 0.0});
  EXPECT_EQ(p.median, 5.0);
  EXPECT_EQ(p.p90, 9.0);
  EXPECT_EQ(p.max, 10.0);
  const Percentiles none = percentiles({});
  EXPECT_EQ(none.max, 0.0);
}

TEST(RunReport, FramesCsvHasOneLinePerFrameAfterItsHeader) {
  slam::FrameResult result;
  result.status = slam::FrameStatus::kTracking;
  result.inliers = 42;
  const std::string csv = frames_csv({frame_record(1.5, result)});
  ASSERT_EQ(csv.rfind("# stamp status inliers prior", 0), 0U);
  const std::string line = csv.substr(csv.find('\n') + 1);
  EXPECT_EQ(line.rfind("1.500000 " + std::string(slam::to_string(slam::FrameStatus::kTracking)) + " 42 0 0 ", 0), 0U)
      << line;
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 2);
}

TEST(RunReport, AClosureIsFalseBeyondAQuarterMetreOrTenDegrees) {
  RelativePoseError error;
  error.has_ground_truth = true;
  error.translation_m = 0.12;
  error.rotation_deg = 6.0;
  EXPECT_FALSE(is_false_closure(error));
  error.translation_m = 0.3;
  EXPECT_TRUE(is_false_closure(error));
  error.translation_m = 0.1;
  error.rotation_deg = 11.0;
  EXPECT_TRUE(is_false_closure(error));
  error.has_ground_truth = false;
  EXPECT_FALSE(is_false_closure(error));
}

TEST(RunReport, WheelsOffWritesTheReason) {
  JsonWriter json;
  json.begin_object();
  write_status_and_wheels(json, {}, nullptr, 0, "--no-wheels");
  json.end_object();
  EXPECT_NE(json.str().find("\"wheels_used\": false, \"wheels_off_reason\": \"--no-wheels\", \"wheel_slip_events\": null"),
            std::string::npos)
      << json.str();
}

}  // namespace
}  // namespace rankslam::eval
