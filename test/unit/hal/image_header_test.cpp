#include "rankslam/hal/image_header.hpp"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <string>
#include <vector>

namespace rankslam::hal {
namespace {

std::vector<unsigned char> encoded(const cv::Mat& image, const std::string& extension) {
  std::vector<unsigned char> bytes;
  EXPECT_TRUE(cv::imencode(extension, image, bytes)) << extension;
  return bytes;
}

void expect_header(const std::vector<unsigned char>& bytes, int width, int height, int channels, int bit_depth) {
  const auto header = read_image_header(bytes);
  ASSERT_TRUE(header.has_value());
  EXPECT_EQ(header->width, width);
  EXPECT_EQ(header->height, height);
  EXPECT_EQ(header->channels, channels);
  EXPECT_EQ(header->bit_depth, bit_depth);
}

TEST(ImageHeader, ReadsWhatEachEncoderWrote) {
  const cv::Mat colour(48, 64, CV_8UC3, cv::Scalar(10, 20, 30));
  const cv::Mat depth(30, 40, CV_16UC1, cv::Scalar(5000));
  const cv::Mat grey(7, 9, CV_8UC1, cv::Scalar(3));
  expect_header(encoded(colour, ".png"), 64, 48, 3, 8);
  expect_header(encoded(depth, ".png"), 40, 30, 1, 16);
  expect_header(encoded(cv::Mat(30, 40, CV_16UC3, cv::Scalar(1, 2, 3)), ".png"), 40, 30, 3, 16);
  expect_header(encoded(cv::Mat(5, 6, CV_8UC4, cv::Scalar(1, 2, 3, 4)), ".png"), 6, 5, 4, 8);
  expect_header(encoded(colour, ".jpg"), 64, 48, 3, 8);
  expect_header(encoded(grey, ".jpg"), 9, 7, 1, 8);
  expect_header(encoded(grey, ".pgm"), 9, 7, 1, 8);
  expect_header(encoded(depth, ".pgm"), 40, 30, 1, 16);
  expect_header(encoded(colour, ".ppm"), 64, 48, 3, 8);
  expect_header(encoded(depth, ".tiff"), 40, 30, 1, 16);
  expect_header(encoded(colour, ".tiff"), 64, 48, 3, 8);
}

TEST(ImageHeader, PnmCommentsAndBlanksAreSkipped) {
  const std::string pgm = "P5\n# a comment\n  320\t240 # another\n65535\n";
  expect_header(std::vector<unsigned char>(pgm.begin(), pgm.end()), 320, 240, 1, 16);
}

TEST(ImageHeader, HugeDimensionsAreReadNotRefused) {
  // A PNG header declaring 30000 x 30000: the caller compares it with what it expects.
  std::vector<unsigned char> bytes = encoded(cv::Mat(2, 2, CV_8UC3), ".png");
  const unsigned char size[] = {0x00, 0x00, 0x75, 0x30};
  std::copy(std::begin(size), std::end(size), bytes.begin() + 16);
  std::copy(std::begin(size), std::end(size), bytes.begin() + 20);
  expect_header(bytes, 30000, 30000, 3, 8);
}

TEST(ImageHeader, AnythingElseOrCutShortIsNoHeader) {
  const std::vector<unsigned char> png = encoded(cv::Mat(4, 4, CV_8UC3), ".png");
  const std::vector<unsigned char> jpeg = encoded(cv::Mat(4, 4, CV_8UC3), ".jpg");
  const std::vector<unsigned char> tiff = encoded(cv::Mat(4, 4, CV_8UC3), ".tiff");
  EXPECT_FALSE(read_image_header({}).has_value());
  EXPECT_FALSE(read_image_header(std::vector<unsigned char>{'h', 'e', 'l', 'l', 'o'}).has_value());
  EXPECT_FALSE(read_image_header(std::span(png).first(20)).has_value());
  EXPECT_FALSE(read_image_header(std::span(jpeg).first(10)).has_value());
  EXPECT_FALSE(read_image_header(std::span(tiff).first(8)).has_value());
  const std::string no_maxval = "P6 640 480";
  EXPECT_FALSE(read_image_header(std::vector<unsigned char>(no_maxval.begin(), no_maxval.end())).has_value());
  const std::string zero_width = "P5 0 480 255\n";
  EXPECT_FALSE(read_image_header(std::vector<unsigned char>(zero_width.begin(), zero_width.end())).has_value());
  std::vector<unsigned char> bad_colour_type = png;
  bad_colour_type[25] = 5;
  EXPECT_FALSE(read_image_header(bad_colour_type).has_value());
}

}  // namespace
}  // namespace rankslam::hal
