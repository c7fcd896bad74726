#include "rankslam/eval/run_report.hpp"

#include <gtest/gtest.h>

#include <sstream>

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

TEST(RunReport, FramesCsvIsCommaSeparatedWithOneHeaderLine) {
  slam::FrameResult result;
  result.status = slam::FrameStatus::kTracking;
  result.inliers = 42;
  const std::string csv = frames_csv({frame_record(1.5, result), frame_record(1.6, result)});
  ASSERT_EQ(csv.rfind("stamp,status,inliers,prior,", 0), 0U);
  std::istringstream in(csv);
  std::string header;
  std::getline(in, header);
  const auto columns = std::count(header.begin(), header.end(), ',') + 1;
  EXPECT_EQ(header.find(' '), std::string::npos);
  int records = 0;
  for (std::string line; std::getline(in, line); ++records) {
    EXPECT_EQ(std::count(line.begin(), line.end(), ',') + 1, columns) << line;
    EXPECT_EQ(line.find(' '), std::string::npos) << line;
  }
  EXPECT_EQ(records, 2);
  const std::string first = csv.substr(csv.find('\n') + 1);
  EXPECT_EQ(first.rfind("1.500000," + std::string(slam::to_string(slam::FrameStatus::kTracking)) + ",42,0,0,", 0), 0U)
      << first;
}

TEST(RunReport, SigmaCoverageCountsErrorsWithinThreeSigma) {
  std::vector<FrameRecord> records(4);
  for (std::size_t i = 0; i < records.size(); ++i) {
    records[i].sigmas = nav::PoseSigmas{0.01, 1.0};
    records[i].gt_position_error_m = 0.01 * static_cast<double>(i + 1);  // 1, 2, 3, 4 sigma
    records[i].gt_yaw_error_deg = -0.5;
  }
  records.push_back(FrameRecord{});  // no sigma, no ground truth: not counted
  const SigmaCoverage coverage = sigma_coverage(records);
  EXPECT_EQ(coverage.frames, 4);
  EXPECT_DOUBLE_EQ(coverage.position_coverage, 0.75);
  EXPECT_DOUBLE_EQ(coverage.yaw_coverage, 1.0);
  EXPECT_DOUBLE_EQ(coverage.median_position_sigma_m, 0.01);
  EXPECT_DOUBLE_EQ(coverage.median_yaw_error_deg, 0.5);
  // Unknown sigmas and errors are empty fields at the end of the line.
  const std::string csv = frames_csv({records.back()});
  EXPECT_NE(csv.find(",,,\n"), std::string::npos) << csv;
}

TEST(RunReport, OdomErrorsAgainstTheGroundTruthRelativeToItsFirstFrame) {
  // Ground truth camera poses from an arbitrary start; the estimate is the same motion in the
  // odom frame (the base at the first frame), 2 cm off sideways at the second frame.
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  T_base_cam.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  T_base_cam.translation() = Eigen::Vector3d(0.2, 0.0, 0.5);
  Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
  start.translation() = Eigen::Vector3d(3.0, -1.0, 0.0);
  Trajectory truth;
  Eigen::Isometry3d moved = Eigen::Isometry3d::Identity();
  moved.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);  // the base 1 m forward
  truth.push_back({1.0, start * T_base_cam});
  truth.push_back({2.0, start * moved * T_base_cam});
  std::vector<FrameRecord> records(2);
  records[0].stamp_s = 1.0;
  records[1].stamp_s = 2.0;
  records[1].T_odom_base.translation() = Eigen::Vector3d(1.0, 0.02, 0.0);
  add_odom_errors(records, truth, T_base_cam);
  ASSERT_TRUE(records[0].gt_position_error_m && records[1].gt_position_error_m && records[1].gt_yaw_error_deg);
  EXPECT_NEAR(*records[0].gt_position_error_m, 0.0, 1e-9);
  EXPECT_NEAR(*records[1].gt_position_error_m, 0.02, 1e-9);
  EXPECT_NEAR(*records[1].gt_yaw_error_deg, 0.0, 1e-9);
}

TEST(RunReport, LoopClosuresCsvLeavesTheErrorFieldsEmptyWithoutGroundTruth) {
  slam::LoopClosure closure;
  closure.stored_stamp_s = 1.0;
  closure.current_stamp_s = 9.0;
  closure.T_stored_current = Eigen::Isometry3d::Identity();
  RelativePoseError off;
  off.has_ground_truth = true;
  off.translation_m = 0.5;
  const std::string csv = loop_closures_csv({closure, closure}, {RelativePoseError{}, off});
  std::istringstream in(csv);
  std::string header, without, with;
  std::getline(in, header);
  std::getline(in, without);
  std::getline(in, with);
  ASSERT_EQ(header.rfind("stored_stamp,current_stamp,", 0), 0U);
  const auto columns = std::count(header.begin(), header.end(), ',');
  EXPECT_EQ(std::count(without.begin(), without.end(), ','), columns) << without;
  EXPECT_EQ(std::count(with.begin(), with.end(), ','), columns) << with;
  EXPECT_EQ(without.substr(without.size() - 3), ",,,") << without;
  EXPECT_EQ(with.substr(with.size() - 2), ",1") << with;
}

TEST(RunReport, TheHeaderGivesTheFormatAndSoftwareVersions) {
  JsonWriter json;
  json.begin_object();
  write_report_header(json, "1.2.3", "replay");
  json.end_object();
  const std::string text = json.str();
  EXPECT_NE(text.find("\"format_version\": " + std::to_string(kReportFormatVersion)), std::string::npos) << text;
  EXPECT_NE(text.find("\"software\": \"rankslam 1.2.3\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"command\": \"replay\""), std::string::npos) << text;
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
