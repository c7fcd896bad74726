// The feature evaluation's own arithmetic on hand-computable cases: repeatability (both overlap
// modes, the common part, one-to-one assignment), the overlap error, the matching inlier ratio
// and the synthetic transformations' homographies.

#include "feature_evaluation.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <numbers>

namespace {

using namespace rankslam::feature_eval;

std::vector<cv::KeyPoint> grid_keypoints(float size) {
  std::vector<cv::KeyPoint> out;
  for (int y = 20; y < 100; y += 20)
    for (int x = 20; x < 140; x += 20) out.emplace_back(cv::Point2f(static_cast<float>(x), static_cast<float>(y)), size);
  return out;
}

RepeatabilityOptions plain_mode() {
  RepeatabilityOptions o;
  o.mode = OverlapMode::plain;
  return o;
}

/// Overlap error of two equal discs of radius r, d apart (closed form).
double disc_error(double r, double d) {
  const double lens = 2 * r * r * std::acos(d / (2 * r)) - 0.5 * d * std::sqrt(4 * r * r - d * d);
  return 1.0 - lens / (2 * std::numbers::pi * r * r - lens);
}

TEST(FeatureEvaluation, IdenticalKeypointsUnderIdentityAreAllRepeated) {
  const auto kp = grid_keypoints(10.0f);
  const cv::Size size(160, 120);
  for (const auto& options : {RepeatabilityOptions{}, plain_mode()}) {
    const RepeatabilityResult r = repeatability(kp, size, kp, size, cv::Matx33d::eye(), options);
    EXPECT_EQ(r.count1, 24);
    EXPECT_EQ(r.count2, 24);
    EXPECT_EQ(r.repeated, 24);
    EXPECT_DOUBLE_EQ(r.repeatability, 1.0);
  }
}

TEST(FeatureEvaluation, ShiftOfHalfTheRadiusFailsPlainButPassesTheNormalisedOverlap) {
  // Discs of radius 5 px, 2.5 px apart: plain error 0.479 (< 0.5); 5 px apart: 0.757 (> 0.5).
  // Normalised to radius 30 with the centres kept, 5 px is error 0.19.
  const cv::Size size(100, 100);
  const std::vector<cv::KeyPoint> a{cv::KeyPoint(cv::Point2f(50, 50), 10.0f)};
  const std::vector<cv::KeyPoint> near{cv::KeyPoint(cv::Point2f(52.5f, 50), 10.0f)};
  const std::vector<cv::KeyPoint> far{cv::KeyPoint(cv::Point2f(55, 50), 10.0f)};
  EXPECT_NEAR(disc_error(5, 2.5), 0.4790, 1e-3);
  EXPECT_NEAR(disc_error(5, 5), 0.7570, 1e-3);
  EXPECT_NEAR(disc_error(30, 5), 0.1916, 1e-3);
  EXPECT_EQ(repeatability(a, size, near, size, cv::Matx33d::eye(), plain_mode()).repeated, 1);
  EXPECT_EQ(repeatability(a, size, far, size, cv::Matx33d::eye(), plain_mode()).repeated, 0);
  EXPECT_EQ(repeatability(a, size, far, size, cv::Matx33d::eye()).repeated, 1);
  // 25 px apart at radius 30 is error 0.68: not repeated even normalised.
  const std::vector<cv::KeyPoint> farther{cv::KeyPoint(cv::Point2f(75, 50), 10.0f)};
  EXPECT_NEAR(disc_error(30, 25), 0.6796, 1e-3);
  EXPECT_EQ(repeatability(a, size, farther, size, cv::Matx33d::eye()).repeated, 0);
}

TEST(FeatureEvaluation, EllipseOverlapErrorMatchesClosedForms) {
  const cv::Matx22d unit = cv::Matx22d::eye();
  EXPECT_NEAR(ellipse_overlap_error({0, 0}, unit, {0, 0}, unit), 0.0, 1e-9);
  // Concentric discs of radius 1 and 2: 1 − 1/4.
  EXPECT_NEAR(ellipse_overlap_error({0, 0}, unit, {0, 0}, unit * 0.25), 0.75, 2e-3);
  // Nested concentric ellipses, axes (2, 1) in (4, 2), tilted alike: 1 − 1/4.
  const double c = std::cos(0.3);
  const double s = std::sin(0.3);
  const cv::Matx22d rot(c, -s, s, c);
  const cv::Matx22d small = rot * cv::Matx22d(0.25, 0, 0, 1.0) * rot.t();
  EXPECT_NEAR(ellipse_overlap_error({3, 4}, small, {3, 4}, small * 0.25), 0.75, 2e-3);
  // Two radius-5 discs 5 px apart, through the polygon path.
  EXPECT_NEAR(ellipse_overlap_error({0, 0}, unit * 0.04, {5, 0}, unit * 0.04), disc_error(5, 5), 3e-3);
}

TEST(FeatureEvaluation, HomographyMapsRegionsAndTheCommonPartCounts) {
  // Image 2 is image 1 enlarged 2× about the origin; regions scale with it, so all repeat.
  const cv::Matx33d h(2, 0, 0, 0, 2, 0, 0, 0, 1);
  const auto kp1 = grid_keypoints(8.0f);
  // Image 2 is 200×240: the points of image 1 with x ≥ 100 (columns 100, 120) fall outside it.
  std::vector<cv::KeyPoint> kp2;
  for (const auto& k : kp1)
    if (k.pt.x < 100) kp2.emplace_back(k.pt * 2.0f, k.size * 2.0f);
  // A point of image 2 whose pre-image (90, 130) lies below image 1: not counted.
  kp2.emplace_back(cv::Point2f(180, 260), 16.0f);
  const RepeatabilityResult r = repeatability(kp1, {160, 120}, kp2, {200, 300}, h, plain_mode());
  EXPECT_EQ(r.count1, 16);
  EXPECT_EQ(r.count2, 16);
  EXPECT_EQ(r.repeated, 16);
  EXPECT_DOUBLE_EQ(r.repeatability, 1.0);
  // The same points at the wrong size (unscaled) overlap 1/4 at best: error 0.75.
  std::vector<cv::KeyPoint> wrong;
  for (const auto& k : kp1) wrong.emplace_back(k.pt * 2.0f, k.size);
  EXPECT_EQ(repeatability(kp1, {160, 120}, wrong, {200, 300}, h, plain_mode()).repeated, 0);
}

TEST(FeatureEvaluation, AssignmentIsOneToOne) {
  const cv::Size size(100, 100);
  const std::vector<cv::KeyPoint> two{cv::KeyPoint(cv::Point2f(50, 50), 10.0f), cv::KeyPoint(cv::Point2f(50.5f, 50), 10.0f)};
  const std::vector<cv::KeyPoint> one{cv::KeyPoint(cv::Point2f(50, 50), 10.0f)};
  const RepeatabilityResult r = repeatability(two, size, one, size, cv::Matx33d::eye(), plain_mode());
  EXPECT_EQ(r.repeated, 1);
  EXPECT_DOUBLE_EQ(r.repeatability, 1.0);  // 1 / min(2, 1)
  const RepeatabilityResult back = repeatability(one, size, two, size, cv::Matx33d::eye(), plain_mode());
  EXPECT_EQ(back.repeated, 1);
}

TEST(FeatureEvaluation, MatchingCountsMutualMatchesAndInliersWithinTwoPixels) {
  // Translation by (10, 0). Descriptors: one-hot rows. Image 2 holds kp 0 and 1 where H puts
  // them, kp 2 3 px off (an outlier), and a decoy near descriptor 0 that is not mutual.
  const cv::Matx33d h(1, 0, 10, 0, 1, 0, 0, 0, 1);
  const cv::Size size(200, 200);
  std::vector<cv::KeyPoint> kp1{cv::KeyPoint(cv::Point2f(20, 20), 8), cv::KeyPoint(cv::Point2f(60, 80), 8),
                                cv::KeyPoint(cv::Point2f(100, 120), 8)};
  std::vector<cv::KeyPoint> kp2{cv::KeyPoint(cv::Point2f(30, 20), 8), cv::KeyPoint(cv::Point2f(71.5f, 80), 8),
                                cv::KeyPoint(cv::Point2f(110, 123), 8), cv::KeyPoint(cv::Point2f(150, 150), 8)};
  cv::Mat d1 = cv::Mat::zeros(3, 128, CV_32F);
  cv::Mat d2 = cv::Mat::zeros(4, 128, CV_32F);
  for (int i = 0; i < 3; ++i) {
    d1.at<float>(i, i) = 1.0f;
    d2.at<float>(i, i) = 1.0f;
  }
  d2.at<float>(3, 0) = 1.0f;  // the decoy: descriptor 0 plus noise
  d2.at<float>(3, 5) = 0.5f;
  const MatchingResult m = match_inliers(kp1, d1, size, kp2, d2, size, h, cv::NORM_L2);
  EXPECT_EQ(m.matches, 3);
  EXPECT_EQ(m.inliers, 2);  // kp 1 is 1.5 px off (inlier), kp 2 is 3 px off (outlier)
  EXPECT_NEAR(m.inlier_ratio, 2.0 / 3.0, 1e-12);
  // The approximate index gives the same answer here.
  const MatchingResult approx = match_inliers(kp1, d1, size, kp2, d2, size, h, cv::NORM_L2, 2.0, 0.0);
  EXPECT_EQ(approx.matches, 3);
  EXPECT_EQ(approx.inliers, 2);
}

cv::Point2d brightest(const cv::Mat& grey) {
  cv::Point at;
  cv::minMaxLoc(grey, nullptr, nullptr, nullptr, &at);
  return {static_cast<double>(at.x), static_cast<double>(at.y)};
}

TEST(FeatureEvaluation, GeometricTransformationsCarryTheirHomography) {
  cv::Mat img = cv::Mat::zeros(61, 81, CV_8U);
  img.at<uchar>(12, 17) = 255;
  for (double deg : {30.0, 90.0, 180.0}) {
    const Transformed t = rotate(img, deg);
    ASSERT_EQ(t.image.size(), img.size());
    const cv::Point2d expected = project(t.h, {17, 12});
    const cv::Point2d got = brightest(t.image);
    EXPECT_LE(std::hypot(expected.x - got.x, expected.y - got.y), 0.75) << deg;
  }
  // A bright 4×4 block: its centroid maps through the scale's homography.
  cv::Mat block = cv::Mat::zeros(60, 80, CV_8U);
  block(cv::Rect(20, 30, 4, 4)).setTo(255);
  for (double f : {0.5, 2.0}) {
    const Transformed t = scale(block, f);
    EXPECT_EQ(t.image.cols, static_cast<int>(80 * f));
    const cv::Moments m = cv::moments(t.image);
    const cv::Point2d expected = project(t.h, {21.5, 31.5});
    EXPECT_NEAR(m.m10 / m.m00, expected.x, 0.05) << f;
    EXPECT_NEAR(m.m01 / m.m00, expected.y, 0.05) << f;
  }
}

TEST(FeatureEvaluation, PhotometricTransformationsKeepTheGeometry) {
  cv::Mat img(40, 50, CV_8U, cv::Scalar(100));
  for (const Transformed& t : {blur(img, 2.0), jpeg(img, 20), brightness(img, 0.5)}) {
    EXPECT_EQ(t.image.size(), img.size()) << t.label;
    EXPECT_EQ(t.h, cv::Matx33d::eye()) << t.label;
  }
  EXPECT_EQ(brightness(img, 0.5).image.at<uchar>(5, 5), 50);
  EXPECT_EQ(brightness(img, 3.0).image.at<uchar>(5, 5), 255);
  EXPECT_EQ(standard_transformations(img).size(), 9u);
}

}  // namespace
