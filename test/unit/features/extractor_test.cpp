// The feature extractor's front door: kinds, descriptor types and refusals.

#include "rankslam/features/extractor.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <stdexcept>

namespace rankslam::features {
namespace {

cv::Mat scene() {
  cv::Mat img(240, 320, CV_8UC1);
  cv::randu(img, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 2.0);
  for (int i = 0; i < 20; ++i) {
    cv::rectangle(img, cv::Rect(10 + 14 * i, 20 + 9 * i, 12, 15), cv::Scalar(40 + 10 * i), -1);
  }
  return img;
}

TEST(FeatureExtractor, NamesRoundTrip) {
  for (const auto kind : {FeatureKind::ros2d, FeatureKind::sift, FeatureKind::orb}) {
    EXPECT_EQ(parse_feature_kind(feature_kind_name(kind)), kind);
  }
  EXPECT_FALSE(parse_feature_kind("surf").has_value());
  EXPECT_FALSE(parse_feature_kind("").has_value());
}

TEST(FeatureExtractor, EveryKindDescribesEveryKeypoint) {
  const cv::Mat img = scene();
  cv::Mat bgr;
  cv::cvtColor(img, bgr, cv::COLOR_GRAY2BGR);
  for (const auto kind : {FeatureKind::ros2d, FeatureKind::sift, FeatureKind::orb}) {
    ExtractorOptions options;
    options.kind = kind;
    options.max_features = 400;
    FeatureExtractor extractor(options);
    std::vector<cv::KeyPoint> kps;
    cv::Mat desc;
    ASSERT_TRUE(extractor.extract(img, kps, desc)) << feature_kind_name(kind);
    ASSERT_GT(kps.size(), 50U) << feature_kind_name(kind);
    EXPECT_LE(kps.size(), 400U) << feature_kind_name(kind);
    EXPECT_EQ(desc.rows, static_cast<int>(kps.size())) << feature_kind_name(kind);
    if (kind == FeatureKind::orb) {
      EXPECT_EQ(desc.type(), CV_8U);
      EXPECT_EQ(desc.cols, 32);
      EXPECT_EQ(extractor.norm_type(), cv::NORM_HAMMING);
    } else {
      EXPECT_EQ(desc.type(), CV_32F);
      EXPECT_EQ(desc.cols, 128);
      EXPECT_EQ(extractor.norm_type(), cv::NORM_L2);
      // Not all zero: the descriptor saw the keypoint's window.
      EXPECT_GT(cv::norm(desc.row(0)), 0.0);
    }
    // A BGR image gives the same features as its grey.
    std::vector<cv::KeyPoint> kps_bgr;
    cv::Mat desc_bgr;
    ASSERT_TRUE(extractor.extract(bgr, kps_bgr, desc_bgr));
    EXPECT_EQ(kps_bgr.size(), kps.size()) << feature_kind_name(kind);
  }
}

TEST(FeatureExtractor, RefusesEmptyAndOddImages) {
  FeatureExtractor extractor;
  std::vector<cv::KeyPoint> kps;
  cv::Mat desc;
  EXPECT_FALSE(extractor.extract(cv::Mat(), kps, desc));
  EXPECT_FALSE(extractor.extract(cv::Mat(100, 100, CV_32FC1, cv::Scalar::all(1)), kps, desc));
  EXPECT_TRUE(kps.empty());
  EXPECT_TRUE(desc.empty());
  ExtractorOptions bad;
  bad.max_features = -3;
  EXPECT_THROW(FeatureExtractor{bad}, std::invalid_argument);
}

}  // namespace
}  // namespace rankslam::features
