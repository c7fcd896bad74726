#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "rankslam/eval/plot.hpp"
#include "test_support.hpp"

namespace rankslam::eval {
namespace {

using test::make_pose;

cv::Mat pixels_of_colour(const cv::Mat& image, const cv::Scalar& bgr) {
  cv::Mat mask;
  cv::inRange(image, bgr, bgr, mask);
  return mask;
}

/// An ellipse of half-axes a (along axis_a) and b (along axis_b) around centre, 10 s at 30 Hz.
Trajectory ellipse(const Eigen::Vector3d& centre, const Eigen::Vector3d& axis_a, double a_m,
                   const Eigen::Vector3d& axis_b, double b_m) {
  Trajectory trajectory;
  for (int k = 0; k < 300; ++k) {
    const double angle = 2.0 * std::numbers::pi * k / 300.0;
    const Eigen::Vector3d p =
        centre + a_m * std::cos(angle) * axis_a + b_m * std::sin(angle) * axis_b;
    trajectory.push_back({50.0 + k / 30.0, make_pose(p, Eigen::Quaterniond::Identity())});
  }
  return trajectory;
}

TEST(TopView, DrawsBothCurvesInTheirColours) {
  const Trajectory truth = test::helix(0.0, 15.0, 100.0);
  Trajectory estimate;
  for (std::size_t k = 0; k < truth.size(); k += 3) {
    Eigen::Isometry3d pose = truth[k].T_world_cam;
    pose.translation() *= 1.15;  // a scale error: the curves do not lie on each other
    estimate.push_back({truth[k].stamp_s, pose});
  }
  TopViewOptions options;
  options.ate_rmse_m = 0.0135;
  options.title = "fr1 test";
  const cv::Mat image = render_top_view(estimate, &truth, options);
  ASSERT_EQ(image.type(), CV_8UC3);
  ASSERT_EQ(image.cols, 800);
  ASSERT_EQ(image.rows, 800);
  // Far more pixels than the legend swatches (about 100 each) have: the curves are drawn.
  EXPECT_GT(cv::countNonZero(pixels_of_colour(image, kGroundTruthBgr)), 800);
  EXPECT_GT(cv::countNonZero(pixels_of_colour(image, kEstimateBgr)), 800);
  EXPECT_GT(cv::countNonZero(pixels_of_colour(image, cv::Scalar(255, 255, 255))), 800 * 800 / 2);
}

TEST(TopView, OnlyTheGroundTruthOverTheEstimatesSpanIsDrawn) {
  // A run over the first third of an ellipse: the rest of the ground truth must not be drawn.
  const Trajectory truth = ellipse(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX(), 3.0, Eigen::Vector3d::UnitY(), 2.0);
  const Trajectory estimate(truth.begin(), truth.begin() + 100);
  Trajectory truth_of_span;
  for (const StampedPose& pose : truth) {
    if (pose.stamp_s >= estimate.front().stamp_s - 0.02 && pose.stamp_s <= estimate.back().stamp_s + 0.02) {
      truth_of_span.push_back(pose);
    }
  }
  ASSERT_LT(truth_of_span.size(), truth.size());
  TopViewOptions options;
  options.max_difference_s = 0.02;
  const cv::Mat whole = render_top_view(estimate, &truth, options);
  const cv::Mat span = render_top_view(estimate, &truth_of_span, options);
  cv::Mat difference;
  cv::absdiff(whole, span, difference);
  EXPECT_EQ(cv::countNonZero(difference.reshape(1)), 0);
}

TEST(TopView, WithoutGroundTruthOnlyTheEstimateIsDrawn) {
  const Trajectory estimate = test::helix(0.0, 15.0, 30.0);
  const cv::Mat image = render_top_view(estimate, nullptr, {});
  EXPECT_EQ(cv::countNonZero(pixels_of_colour(image, kGroundTruthBgr)), 0);
  EXPECT_GT(cv::countNonZero(pixels_of_colour(image, kEstimateBgr)), 800);
}

TEST(TopView, BothAxesHaveTheSameScale) {
  // A circle of 1 m radius must stay round: equal width and height in pixels.
  const Trajectory circle =
      ellipse({0.5, -0.2, 1.0}, Eigen::Vector3d::UnitX(), 1.0, Eigen::Vector3d::UnitY(), 1.0);
  TopViewOptions options;
  options.show_legend = false;  // its swatch would count as curve pixels
  options.width_px = 1000;      // not square, so an unequal scale would show
  options.height_px = 600;
  const cv::Mat image = render_top_view(circle, nullptr, options);
  const cv::Rect box = cv::boundingRect(pixels_of_colour(image, kEstimateBgr));
  EXPECT_GT(box.height, 300);
  // The start marker (radius 6 px) may stick out on one side; an unequal scale would be off by
  // the 1000:600 aspect, some 180 px.
  EXPECT_NEAR(box.width, box.height, 10) << box;
}

TEST(TopView, ProjectsOntoThePrincipalPlane) {
  // In TUM's camera-world frames the motion can lie in x-z: a projection onto x-y would show a
  // line. The principal plane shows the 2:1 ellipse.
  const Trajectory in_xz =
      ellipse({1.0, 0.3, 2.0}, Eigen::Vector3d::UnitX(), 1.0, Eigen::Vector3d::UnitZ(), 0.5);
  TopViewOptions options;
  options.show_legend = false;
  const cv::Mat image = render_top_view(in_xz, nullptr, options);
  const cv::Rect box = cv::boundingRect(pixels_of_colour(image, kEstimateBgr));
  ASSERT_GT(box.height, 50);
  EXPECT_NEAR(static_cast<double>(box.width) / box.height, 2.0, 0.1) << box;
}

TEST(TopView, SameMotionInAnotherFrameGivesTheSamePicture) {
  // Robot base frame (motion in x-y) and the same motion in a frame turned by -90 deg about x
  // and moved: the view depends only on the motion.
  const Trajectory base = test::helix(0.0, 12.0, 30.0);
  Trajectory planar;
  for (const StampedPose& pose : base) {
    Eigen::Isometry3d flat = pose.T_world_cam;
    flat.translation().z() = 0.0;
    planar.push_back({pose.stamp_s, flat});
  }
  const Eigen::Isometry3d T_other_base = make_pose(
      {3.0, -2.0, 7.0},
      Eigen::Quaterniond(Eigen::AngleAxisd(-std::numbers::pi / 2, Eigen::Vector3d::UnitX())));
  Trajectory moved;
  for (const StampedPose& pose : planar)
    moved.push_back({pose.stamp_s, T_other_base * pose.T_world_cam});

  const cv::Mat a = render_top_view(planar, nullptr, {});
  const cv::Mat b = render_top_view(moved, nullptr, {});
  cv::Mat difference;
  cv::absdiff(a, b, difference);
  cv::Mat gray;
  cv::extractChannel(difference, gray, 0);
  cv::Mat changed = gray > 40;
  EXPECT_LT(cv::countNonZero(changed), a.total() / 500) << "pictures differ";
  EXPECT_GT(cv::countNonZero(pixels_of_colour(b, kEstimateBgr)), 800);
}

TEST(TopView, EmptyOrDegenerateInputStillRenders) {
  TopViewOptions no_legend;
  no_legend.show_legend = false;
  const cv::Mat empty = render_top_view({}, nullptr, no_legend);
  ASSERT_EQ(empty.type(), CV_8UC3);
  EXPECT_FALSE(empty.empty());
  EXPECT_EQ(cv::countNonZero(pixels_of_colour(empty, kEstimateBgr)), 0);
  EXPECT_FALSE(render_top_view({}, nullptr, {}).empty());

  const Trajectory one_point = {{1.0, make_pose({1, 2, 3}, Eigen::Quaterniond::Identity())}};
  const cv::Mat single = render_top_view(one_point, &one_point, no_legend);
  EXPECT_GT(cv::countNonZero(pixels_of_colour(single, kEstimateBgr)), 0);

  Trajectory with_nan = test::helix(0.0, 5.0, 30.0);
  with_nan[10].T_world_cam.translation().x() = std::nan("");
  TopViewOptions tiny;
  tiny.width_px = -5;
  tiny.height_px = 1;
  const cv::Mat clamped = render_top_view(with_nan, nullptr, tiny);
  EXPECT_EQ(clamped.cols, 200);
  EXPECT_EQ(clamped.rows, 200);
}

TEST(TopView, PngRoundTripAndAtomicWrite) {
  const Trajectory truth = test::helix(0.0, 10.0, 100.0);
  const cv::Mat image = render_top_view(truth, &truth, {});
  const std::vector<uchar> png = encode_png(image);
  ASSERT_GT(png.size(), 8U);
  const cv::Mat decoded = cv::imdecode(png, cv::IMREAD_COLOR);
  ASSERT_EQ(decoded.size(), image.size());
  EXPECT_EQ(cv::norm(decoded, image, cv::NORM_INF), 0.0);
  EXPECT_TRUE(encode_png(cv::Mat()).empty());

  const test::TempFile file("top_view.png");
  const std::string error = write_png(file.path(), image);
  ASSERT_TRUE(error.empty()) << error;
  const cv::Mat read = cv::imread(file.path().string(), cv::IMREAD_COLOR);
  EXPECT_EQ(cv::norm(read, image, cv::NORM_INF), 0.0);
  EXPECT_FALSE(write_png(file.path(), cv::Mat()).empty());
}

}  // namespace
}  // namespace rankslam::eval
