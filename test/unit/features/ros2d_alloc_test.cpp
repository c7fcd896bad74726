// ROS2D's detect() allocates nothing once reserved (the loop is fixed-memory).

#include "allocation_counter.hpp"
#include "rankslam/features/ros2d.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <random>
#include <vector>

namespace rankslam::features {
namespace {

TEST(Ros2dAllocations, DetectAllocatesNothingOnceReserved) {
  // Smooth noise with a few sharp discs: salient points among smooth ones.
  cv::Mat img(120, 160, CV_8UC1);
  cv::randu(img, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 3.0);
  for (int i = 0; i < 12; ++i) {
    cv::circle(img, cv::Point(13 * i + 5, 9 * i + 7), 3 + i % 6, cv::Scalar(20 * (i % 12)), -1);
  }
  cv::Mat other = img(cv::Rect(3, 5, 150, 100)).clone();  // smaller than the reserve
  Ros2dOptions options;
  options.max_features = 2000;
  Ros2dDetector detector(options);
  detector.reserve(img.size());
  std::vector<cv::KeyPoint> kps;
  kps.reserve(static_cast<std::size_t>(options.max_features));
  ASSERT_TRUE(detector.detect(img, kps));  // fills the lazy tables once
  ASSERT_FALSE(kps.empty());
  test_support::CountAllocations count;
  ASSERT_TRUE(detector.detect(other, kps));
  ASSERT_TRUE(detector.detect(img, kps));
  EXPECT_EQ(count.allocations(), 0);
  EXPECT_EQ(static_cast<int>(kps.size()), detector.stats().features);
  EXPECT_GT(kps.size(), 200U);
}

}  // namespace
}  // namespace rankslam::features
