#include <fstream>
#include <limits>
#include <string>

#include <gtest/gtest.h>

#include "rankslam/eval/trajectory.hpp"
#include "test_support.hpp"

namespace rankslam::eval {
namespace {

using test::TempFile;

TEST(TumTrajectoryParse, SkipsCommentsAndBlankLinesAndAcceptsTabsCommasAndCrlf) {
  const std::string text =
      "# ground truth trajectory\n"
      "\n"
      "   # indented comment\n"
      "1305031098.6659 1.3563 0.6305 1.6380 0.6132 0.5962 -0.3311 -0.3986\r\n"
      "   \t \n"
      "1305031098.6758\t1.3543,0.6306 1.6360\t0 0 0 2\n"
      "1305031098.7 +1e-3 -2.5E+1 0 0 0 0 1";  // no final newline
  const Result<Trajectory> parsed = parse_tum_trajectory(text, "inline.txt");
  ASSERT_TRUE(parsed.ok()) << parsed.error();
  const Trajectory& trajectory = parsed.value();
  ASSERT_EQ(trajectory.size(), 3U);

  EXPECT_DOUBLE_EQ(trajectory[0].stamp_s, 1305031098.6659);
  EXPECT_TRUE(
      trajectory[0].T_world_cam.translation().isApprox(Eigen::Vector3d(1.3563, 0.6305, 1.6380)));
  const Eigen::Quaterniond expected_q =
      Eigen::Quaterniond(-0.3986, 0.6132, 0.5962, -0.3311).normalized();
  EXPECT_TRUE(trajectory[0].T_world_cam.linear().isApprox(expected_q.toRotationMatrix(), 1e-12));

  // A quaternion of length 2 is normalised.
  EXPECT_TRUE(trajectory[1].T_world_cam.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-15));
  EXPECT_TRUE(
      trajectory[1].T_world_cam.translation().isApprox(Eigen::Vector3d(1.3543, 0.6306, 1.6360)));
  EXPECT_DOUBLE_EQ(trajectory[2].T_world_cam.translation().x(), 1e-3);
  EXPECT_DOUBLE_EQ(trajectory[2].T_world_cam.translation().y(), -25.0);
}

TEST(TumTrajectoryParse, QuaternionOrderIsXyzw) {
  // qz = qw = sqrt(1/2): 90 degrees about z, so the camera's x axis points along world y.
  const Result<Trajectory> parsed =
      parse_tum_trajectory("5.0 0 0 0 0 0 0.70710678 0.70710678\n", "q.txt");
  ASSERT_TRUE(parsed.ok()) << parsed.error();
  const Eigen::Vector3d x_in_world =
      parsed.value()[0].T_world_cam.linear() * Eigen::Vector3d::UnitX();
  EXPECT_TRUE(x_in_world.isApprox(Eigen::Vector3d::UnitY(), 1e-8)) << x_in_world.transpose();
}

TEST(TumTrajectoryParse, EmptyTextIsAnEmptyTrajectory) {
  const Result<Trajectory> parsed = parse_tum_trajectory("# only a header\n\n", "empty.txt");
  ASSERT_TRUE(parsed.ok()) << parsed.error();
  EXPECT_TRUE(parsed.value().empty());
}

struct BadLine {
  const char* text;
  const char* expected_location;
  const char* expected_cause;
};

class TumTrajectoryParseError : public ::testing::TestWithParam<BadLine> {};

TEST_P(TumTrajectoryParseError, NamesFileLineAndCause) {
  const Result<Trajectory> parsed = parse_tum_trajectory(GetParam().text, "traj.txt");
  ASSERT_FALSE(parsed.ok());
  EXPECT_EQ(parsed.error().rfind(GetParam().expected_location, 0), 0U) << parsed.error();
  EXPECT_NE(parsed.error().find(GetParam().expected_cause), std::string::npos) << parsed.error();
}

constexpr const char* kGoodLine = "1.0 0 0 0 0 0 0 1\n";

INSTANTIATE_TEST_SUITE_P(
    Cases, TumTrajectoryParseError,
    ::testing::Values(
        BadLine{"# header\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", "traj.txt:3: ", "found 7"},
        BadLine{"1.0 0 0 0 0 0 0 1 9\n", "traj.txt:1: ", "found 9"},
        BadLine{"1.0 0 0 0 0 0 0 1\n\n2.0 abc 0 0 0 0 0 1\n",
                "traj.txt:3: ", "field 2 (tx) 'abc' is not a number"},
        BadLine{"1.0 0 0 0 0 0 0 1x\n", "traj.txt:1: ", "field 8 (qw)"},
        BadLine{"1.0 0 0 0 0 0 0 1\n2.0 0 nan 0 0 0 0 1\n",
                "traj.txt:2: ", "field 3 (ty) 'nan' is not finite"},
        BadLine{"inf 0 0 0 0 0 0 1\n", "traj.txt:1: ", "field 1 (timestamp)"},
        BadLine{"1.0 0 0 0 0 0 0 0\n", "traj.txt:1: ", "cannot be normalised"},
        BadLine{"1.0 0 0 0 1e-9 0 0 0\n", "traj.txt:1: ", "cannot be normalised"},
        BadLine{"1.0 0 0 0 1e300 1e300 0 0\n", "traj.txt:1: ", "cannot be normalised"},
        BadLine{"1.0 0 0 0 0 0 0 1 # trailing comment\n", "traj.txt:1: ", "found 11"},
        BadLine{"1.0 0 0 0 0 0 0 1\n2.0 1e400 0 0 0 0 0 1\n", "traj.txt:2: ",
                "field 2 (tx) '1e400' is out of range"},
        BadLine{"1.0 0 0 0 0 0 0 1\n1..0 0 0 0 0 0 0 1\n", "traj.txt:2: ", "field 1 (timestamp)"}));

TEST(TumTrajectoryParse, GoodLineIsAccepted) {
  // Guards the parameterised cases above: they fail because of the bad line, not the good one.
  EXPECT_TRUE(parse_tum_trajectory(kGoodLine, "traj.txt").ok());
}

TEST(TumTrajectoryRead, MissingFileNamesThePath) {
  const Result<Trajectory> read = read_tum_trajectory("/nonexistent/dir/trajectory.txt");
  ASSERT_FALSE(read.ok());
  EXPECT_NE(read.error().find("/nonexistent/dir/trajectory.txt"), std::string::npos)
      << read.error();
}

TEST(TumTrajectoryRead, ErrorInFileNamesThePathAndLine) {
  const TempFile file("bad_line.txt");
  {
    std::ofstream out(file.path());
    out << "# timestamp tx ty tz qx qy qz qw\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0\n";
  }
  const Result<Trajectory> read = read_tum_trajectory(file.path());
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.error().rfind(file.path().string() + ":3: ", 0), 0U) << read.error();
}

TEST(TumTrajectoryWrite, RoundTripKeepsStampsPositionsAndRotations) {
  Trajectory original = test::helix(1305031102.160407, 3.0, 30.0);
  // Stamps as a recorder writes them: whole microseconds.
  for (StampedPose& pose : original) pose.stamp_s = std::round(pose.stamp_s * 1e6) / 1e6;
  // A rotation whose quaternion has w < 0 in Eigen's conversion must survive too.
  original.push_back(
      {original.back().stamp_s + 0.5,
       test::make_pose({-1.0, 2.0, 1e-7}, Eigen::Quaterniond(Eigen::AngleAxisd(
                                              3.1, Eigen::Vector3d(1, 2, 3).normalized())))});

  const TempFile file("round_trip.txt");
  const std::string error = write_tum_trajectory(file.path(), original);
  ASSERT_TRUE(error.empty()) << error;
  const Result<Trajectory> read = read_tum_trajectory(file.path());
  ASSERT_TRUE(read.ok()) << read.error();
  ASSERT_EQ(read.value().size(), original.size());
  for (std::size_t i = 0; i < original.size(); ++i) {
    const StampedPose& a = original[i];
    const StampedPose& b = read.value()[i];
    EXPECT_NEAR(a.stamp_s, b.stamp_s, 5e-7) << i;
    EXPECT_LT((a.T_world_cam.translation() - b.T_world_cam.translation()).norm(), 1e-8) << i;
    const double angle_rad =
        Eigen::AngleAxisd(a.T_world_cam.linear().transpose() * b.T_world_cam.linear()).angle();
    EXPECT_LT(angle_rad, 1e-8) << i;
  }
}

TEST(TumTrajectoryWrite, FormatHasHeaderAndSixDecimalStamps) {
  const Trajectory trajectory = {{12.5, Eigen::Isometry3d::Identity()}};
  EXPECT_EQ(format_tum_trajectory(trajectory),
            "# timestamp tx ty tz qx qy qz qw\n12.500000 0 0 0 0 0 0 1\n");
}

TEST(TumTrajectoryWrite, ExtremeFiniteValuesKeepEveryLineWhole) {
  const double big = std::numeric_limits<double>::max();
  Trajectory trajectory = {{-big, test::make_pose({-big, big, -1e-300}, Eigen::Quaterniond::Identity())},
                           {1.0, Eigen::Isometry3d::Identity()}};
  const Result<Trajectory> read = parse_tum_trajectory(format_tum_trajectory(trajectory), "extreme");
  ASSERT_TRUE(read.ok()) << read.error();
  ASSERT_EQ(read.value().size(), 2U);
  EXPECT_EQ(read.value()[0].stamp_s, -big);
  EXPECT_EQ(read.value()[1].stamp_s, 1.0);
}

TEST(TumTrajectoryWrite, RefusesNonFinitePoseAndNamesIt) {
  Trajectory trajectory = test::helix(0.0, 1.0, 10.0);
  trajectory[4].T_world_cam.translation().y() = std::numeric_limits<double>::quiet_NaN();
  const TempFile file("non_finite.txt");
  const std::string error = write_tum_trajectory(file.path(), trajectory);
  EXPECT_NE(error.find("pose 4"), std::string::npos) << error;
  EXPECT_FALSE(std::filesystem::exists(file.path()));
}

TEST(TumTrajectoryWrite, UnwritableDirectoryIsAnError) {
  const std::string error =
      write_tum_trajectory("/nonexistent/dir/out.txt", test::helix(0.0, 1.0, 10.0));
  EXPECT_NE(error.find("/nonexistent/dir/out.txt"), std::string::npos) << error;
}

}  // namespace
}  // namespace rankslam::eval
