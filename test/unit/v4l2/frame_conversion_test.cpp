#include "rankslam/v4l2/frame_conversion.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

namespace rankslam::v4l2 {
namespace {

// ITU-R BT.601 limited-range YCbCr to BGR, the conversion V4L2 YUYV cameras use.
cv::Vec3b bt601_to_bgr(int y, int u, int v) {
  const double luma = 1.164 * (y - 16);
  const auto clamp = [](double value) { return static_cast<std::uint8_t>(std::clamp(std::lround(value), 0L, 255L)); };
  return {clamp(luma + 2.018 * (u - 128)), clamp(luma - 0.813 * (v - 128) - 0.391 * (u - 128)),
          clamp(luma + 1.596 * (v - 128))};
}

TEST(Fourcc, RoundTripsThroughText) {
  EXPECT_EQ(fourcc_to_string(fourcc('Y', 'U', 'Y', 'V')), "YUYV");
  EXPECT_EQ(fourcc_to_string(fourcc('M', 'J', 'P', 'G')), "MJPG");
  EXPECT_EQ(fourcc_to_string(fourcc('Y', '1', '6', ' ') | 0x80000000U), "Y16?");
}

TEST(YuyvToBgr, MatchesBt601PixelByPixelInPairOrder) {
  constexpr int kWidth = 64;
  constexpr int kHeight = 8;
  cv::Mat packed(kHeight, kWidth, CV_8UC2);
  cv::RNG rng(7);
  rng.fill(packed, cv::RNG::UNIFORM, 16, 236);
  cv::Mat bgr;
  ASSERT_TRUE(yuyv_to_bgr(packed.data, packed.total() * 2, kWidth, kHeight, kWidth * 2, bgr));
  ASSERT_EQ(bgr.type(), CV_8UC3);
  int worst = 0;
  for (int row = 0; row < kHeight; ++row) {
    const std::uint8_t* line = packed.ptr<std::uint8_t>(row);
    for (int column = 0; column < kWidth; ++column) {
      const int pair = column / 2 * 4;  // Y0 U Y1 V
      const cv::Vec3b expected = bt601_to_bgr(line[pair + (column % 2) * 2], line[pair + 1], line[pair + 3]);
      const cv::Vec3b actual = bgr.at<cv::Vec3b>(row, column);
      for (int channel = 0; channel < 3; ++channel) worst = std::max(worst, std::abs(actual[channel] - expected[channel]));
    }
  }
  EXPECT_LE(worst, 2);
}

TEST(YuyvToBgr, KnownColours) {
  // White and black in one pair, then BT.601 red.
  const std::vector<std::uint8_t> packed{235, 128, 16, 128, 81, 90, 81, 240};
  cv::Mat bgr;
  ASSERT_TRUE(yuyv_to_bgr(packed.data(), packed.size(), 4, 1, 8, bgr));
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(255, 255, 255));
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 1), cv::Vec3b(0, 0, 0));
  const cv::Vec3b red = bgr.at<cv::Vec3b>(0, 2);
  EXPECT_LE(red[0], 2);
  EXPECT_LE(red[1], 2);
  EXPECT_GE(red[2], 252);
}

TEST(YuyvToBgr, HonoursRowPaddingAndReusesTheImage) {
  constexpr int kWidth = 4;
  constexpr std::size_t kPitch = 12;  // 8 bytes of pixels, 4 of padding
  std::vector<std::uint8_t> packed(kPitch * 2, 0xEE);
  const std::uint8_t grey[] = {126, 128, 126, 128, 126, 128, 126, 128};
  std::copy(std::begin(grey), std::end(grey), packed.begin());
  std::copy(std::begin(grey), std::end(grey), packed.begin() + kPitch);
  cv::Mat bgr(2, kWidth, CV_8UC3);
  const std::uint8_t* memory = bgr.data;
  ASSERT_TRUE(yuyv_to_bgr(packed.data(), packed.size(), kWidth, 2, kPitch, bgr));
  EXPECT_EQ(bgr.data, memory);
  for (int row = 0; row < 2; ++row) {
    for (int column = 0; column < kWidth; ++column) EXPECT_EQ(bgr.at<cv::Vec3b>(row, column), cv::Vec3b(128, 128, 128));
  }
}

TEST(YuyvToBgr, RefusesShortOrMalformedInput) {
  std::vector<std::uint8_t> packed(8 * 2 * 2 - 1, 128);  // one byte short of 8x2
  cv::Mat bgr(2, 8, CV_8UC3, cv::Scalar(1, 2, 3));
  EXPECT_FALSE(yuyv_to_bgr(packed.data(), packed.size(), 8, 2, 16, bgr));
  EXPECT_EQ(bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(1, 2, 3));
  EXPECT_FALSE(yuyv_to_bgr(packed.data(), packed.size(), 7, 1, 16, bgr));  // odd width
  EXPECT_FALSE(yuyv_to_bgr(packed.data(), packed.size(), 8, 1, 8, bgr));   // pitch below a row
  EXPECT_FALSE(yuyv_to_bgr(nullptr, 64, 8, 1, 16, bgr));
}

std::vector<std::uint8_t> test_jpeg(int width, int height) {
  cv::Mat image(height, width, CV_8UC3);
  for (int row = 0; row < height; ++row) {
    for (int column = 0; column < width; ++column) {
      image.at<cv::Vec3b>(row, column) = cv::Vec3b(static_cast<std::uint8_t>(4 * column), static_cast<std::uint8_t>(5 * row), 90);
    }
  }
  std::vector<std::uint8_t> encoded;
  EXPECT_TRUE(cv::imencode(".jpg", image, encoded, {cv::IMWRITE_JPEG_QUALITY, 95}));
  return encoded;
}

TEST(MjpegToBgr, DecodesIntoThePreallocatedImage) {
  const auto jpeg = test_jpeg(64, 48);
  cv::Mat bgr(48, 64, CV_8UC3);
  const std::uint8_t* memory = bgr.data;
  ASSERT_TRUE(mjpeg_to_bgr(jpeg.data(), jpeg.size(), 64, 48, bgr));
  EXPECT_EQ(bgr.data, memory);
  const cv::Mat reference = cv::imdecode(jpeg, cv::IMREAD_COLOR);
  EXPECT_EQ(cv::norm(bgr, reference, cv::NORM_INF), 0.0);
}

TEST(MjpegToBgr, AcceptsZeroPaddingAfterTheImage) {
  auto jpeg = test_jpeg(32, 16);
  jpeg.resize(jpeg.size() + 100, 0);
  cv::Mat bgr;
  EXPECT_TRUE(mjpeg_to_bgr(jpeg.data(), jpeg.size(), 32, 16, bgr));
}

TEST(MjpegToBgr, RefusesTruncatedForeignAndMisSizedFrames) {
  const auto jpeg = test_jpeg(64, 48);
  cv::Mat bgr(48, 64, CV_8UC3);
  EXPECT_FALSE(mjpeg_to_bgr(jpeg.data(), jpeg.size() / 2, 64, 48, bgr));  // cut short on the wire
  EXPECT_EQ(bgr.size(), cv::Size(64, 48));
  EXPECT_EQ(bgr.type(), CV_8UC3);

  const std::vector<std::uint8_t> foreign(1000, 0x55);
  EXPECT_FALSE(mjpeg_to_bgr(foreign.data(), foreign.size(), 64, 48, bgr));

  // Start and end markers with garbage between: no frame header for the decoder to use.
  std::vector<std::uint8_t> corrupt(500, 0x55);
  corrupt[0] = 0xFF;
  corrupt[1] = 0xD8;
  corrupt[498] = 0xFF;
  corrupt[499] = 0xD9;
  EXPECT_FALSE(mjpeg_to_bgr(corrupt.data(), corrupt.size(), 64, 48, bgr));
  EXPECT_EQ(bgr.size(), cv::Size(64, 48));

  EXPECT_FALSE(mjpeg_to_bgr(jpeg.data(), jpeg.size(), 32, 48, bgr));  // not the negotiated size
  EXPECT_EQ(bgr.size(), cv::Size(32, 48));
}

}  // namespace
}  // namespace rankslam::v4l2
