#include "rankslam/slam/image_source.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <random>

namespace rankslam::slam {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;
constexpr unsigned char kBackground = 60;
constexpr unsigned char kPatch = 150;
const cv::Rect kPatchRect(40, 30, 50, 40);

// A uniform IR background with one large reflective patch and projector speckle: isolated
// single pixels and 2×2 dots at full brightness, none touching the patch.
cv::Mat speckle_image(std::vector<cv::Point>& dots) {
  cv::Mat image(kHeight, kWidth, CV_8UC1, cv::Scalar(kBackground));
  image(kPatchRect).setTo(cv::Scalar(kPatch));
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> column(4, kWidth - 6);
  std::uniform_int_distribution<int> row(4, kHeight - 6);
  const cv::Rect keep_clear(kPatchRect.x - 6, kPatchRect.y - 6, kPatchRect.width + 12, kPatchRect.height + 12);
  while (dots.size() < 60) {
    const cv::Point dot(column(rng), row(rng));
    if (keep_clear.contains(dot)) continue;
    bool near_other = false;
    for (const cv::Point& other : dots) near_other = near_other || std::abs(other.x - dot.x) + std::abs(other.y - dot.y) < 6;
    if (near_other) continue;
    image.at<unsigned char>(dot) = 255;
    if (dots.size() % 2 == 0) image(cv::Rect(dot.x, dot.y, 2, 2)).setTo(cv::Scalar(255));
    dots.push_back(dot);
  }
  return image;
}

TEST(InfraredFilter, RemovesIsolatedSpeckleAndKeepsLargeStructure) {
  std::vector<cv::Point> dots;
  const cv::Mat ir = speckle_image(dots);
  InfraredFilter filter(kWidth, kHeight);
  cv::Mat out;
  ASSERT_TRUE(filter.apply(ir, out));
  ASSERT_EQ(out.type(), CV_8UC1);
  const unsigned char background = 90;  // 60 · 1.5
  const unsigned char patch = 225;      // 150 · 1.5
  for (const cv::Point& dot : dots) {
    EXPECT_EQ(out.at<unsigned char>(dot), background) << "dot at " << dot.x << "," << dot.y;
    EXPECT_EQ(out.at<unsigned char>(dot + cv::Point(1, 1)), background) << "dot at " << dot.x << "," << dot.y;
  }
  // Nothing brighter than the background is left outside the patch.
  cv::Mat outside = out.clone();
  outside(kPatchRect).setTo(cv::Scalar(0));
  double brightest = 0.0;
  cv::minMaxLoc(outside, nullptr, &brightest);
  EXPECT_EQ(brightest, background);
  // The patch keeps its extent (the opening and the median only round its corners).
  const cv::Rect inner(kPatchRect.x + 2, kPatchRect.y + 2, kPatchRect.width - 4, kPatchRect.height - 4);
  double darkest_inside = 0.0;
  cv::minMaxLoc(out(inner), &darkest_inside, nullptr);
  EXPECT_EQ(darkest_inside, patch);
  EXPECT_EQ(out.at<unsigned char>(kPatchRect.y + kPatchRect.height / 2, kPatchRect.x - 2), background);
  EXPECT_EQ(out.at<unsigned char>(kPatchRect.y + kPatchRect.height / 2, kPatchRect.x + 1), patch);
}

TEST(InfraredFilter, BrightnessStepIsExactlyOneAndAHalfTimes) {
  InfraredFilter filter(256, 1);
  cv::Mat ramp(1, 256, CV_8UC1);
  for (int v = 0; v < 256; ++v) ramp.at<unsigned char>(0, v) = static_cast<unsigned char>(v);
  cv::Mat out;
  filter.brighten(ramp, out);
  for (int v = 0; v < 256; ++v) {
    // 1.5·v rounded half up, saturated.
    const int expected = std::min(255, (3 * v + 1) / 2);
    EXPECT_EQ(out.at<unsigned char>(0, v), expected) << v;
  }
  EXPECT_EQ(out.at<unsigned char>(0, 1), 2);
  EXPECT_EQ(out.at<unsigned char>(0, 100), 150);
  EXPECT_EQ(out.at<unsigned char>(0, 170), 255);
}

TEST(InfraredFilter, Reads10BitIrAndRejectsOtherImages) {
  InfraredFilter filter(kWidth, kHeight);
  cv::Mat out;
  const cv::Mat ten_bit(kHeight, kWidth, CV_16UC1, cv::Scalar(400));  // 400 / 4 = 100
  ASSERT_TRUE(filter.apply(ten_bit, out));
  EXPECT_EQ(cv::countNonZero(out != 150), 0);

  cv::Mat untouched(kHeight, kWidth, CV_8UC1, cv::Scalar(7));
  EXPECT_FALSE(filter.apply(cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar::all(100)), untouched));
  EXPECT_FALSE(filter.apply(cv::Mat(kHeight + 1, kWidth, CV_8UC1, cv::Scalar(100)), untouched));
  EXPECT_FALSE(filter.apply(cv::Mat(), untouched));
  EXPECT_EQ(cv::countNonZero(untouched != 7), 0);
}

TEST(MeanBrightness, IsTheMeanGreyLevel) {
  cv::Mat gray(10, 10, CV_8UC1, cv::Scalar(20));
  gray(cv::Rect(0, 0, 10, 5)).setTo(cv::Scalar(40));
  EXPECT_DOUBLE_EQ(mean_brightness(gray), 30.0);
  EXPECT_DOUBLE_EQ(mean_brightness(cv::Mat()), 0.0);
}

}  // namespace
}  // namespace rankslam::slam
