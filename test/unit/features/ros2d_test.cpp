// The ROS2D detector (docs/methods.md §15) on images whose residuals can be computed by hand.

#include "rankslam/features/ros2d.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

namespace rankslam::features {
namespace {

// The 1-D kernel of eq. 7.1 for σ at half-width r, normalised to sum 1.
std::vector<double> kernel(double sigma, int r) {
  std::vector<double> g;
  double sum = 0.0;
  for (int i = -r; i <= r; ++i) {
    g.push_back(std::exp(-i * i / (2.0 * sigma * sigma)));
    sum += g.back();
  }
  for (double& v : g) v /= sum;
  return g;
}

// Eq. 7.2 evaluated directly over the (2r+1)² window at (x, y).
double direct_residual(const cv::Mat& img, int x, int y, const std::vector<double>& g, int r) {
  double sum = 0.0;
  const double c = img.at<float>(y, x);
  for (int j = -r; j <= r; ++j) {
    for (int i = -r; i <= r; ++i) {
      const double d = c - static_cast<double>(img.at<float>(y + j, x + i));
      sum += g[static_cast<std::size_t>(j + r)] * g[static_cast<std::size_t>(i + r)] * d * d;
    }
  }
  return sum;
}

// A textured image: smoothed noise plus a few bright discs, fixed seed.
cv::Mat textured(int w, int h, unsigned seed) {
  cv::Mat img(h, w, CV_8UC1);
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> u(0, 255);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) img.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(u(rng));
  }
  cv::GaussianBlur(img, img, cv::Size(0, 0), 3.0);
  for (int i = 0; i < 12; ++i) {
    cv::circle(img, cv::Point(u(rng) * w / 256, u(rng) * h / 256), 3 + u(rng) % 8, cv::Scalar(u(rng)), -1);
  }
  return img;
}

TEST(Ros2d, SingleBrightPixelIsTheOnlyPeakWithItsHandComputedResidual) {
  // One pixel of 255 on black: its residual is Σ_j w_j·255² over j ≠ centre = 255²·(1 − g0²);
  // every other point's residual is smaller, and most are exactly 0.
  Ros2dOptions options;
  options.octaves = 2;
  options.layers = 1;
  options.equalize = false;
  options.local_peaks_only = true;
  options.orientation = false;
  Ros2dDetector detector(options);
  const int r = detector.kernel_radius();
  EXPECT_EQ(r, 5);  // ⌈3·1.6⌉
  cv::Mat img = cv::Mat::zeros(96, 128, CV_8UC1);
  img.at<std::uint8_t>(40, 60) = 255;
  std::vector<cv::KeyPoint> kps;
  ASSERT_TRUE(detector.detect(img, kps));
  ASSERT_EQ(kps.size(), 2U);
  const double g0 = kernel(1.6, r)[static_cast<std::size_t>(r)];
  // Octave 0: the pixel itself.
  EXPECT_FLOAT_EQ(kps[0].pt.x, 60.0F);
  EXPECT_FLOAT_EQ(kps[0].pt.y, 40.0F);
  EXPECT_NEAR(static_cast<double>(kps[0].response), 255.0 * 255.0 * (1.0 - g0 * g0), 0.05);
  EXPECT_FLOAT_EQ(kps[0].size, 3.2F);
  EXPECT_EQ(kps[0].octave, 0);
  // Octave 1: the 2×2 block holding it averages to 63.75, centred at (60.5, 40.5) in full pixels.
  EXPECT_FLOAT_EQ(kps[1].pt.x, 60.5F);
  EXPECT_FLOAT_EQ(kps[1].pt.y, 40.5F);
  EXPECT_NEAR(static_cast<double>(kps[1].response), 63.75 * 63.75 * (1.0 - g0 * g0), 0.01);
  EXPECT_FLOAT_EQ(kps[1].size, 6.4F);
  EXPECT_EQ(kps[1].octave & 0xff, 1);
  // Without the peak test the whole second group comes back: every non-zero residual.
  options.local_peaks_only = false;
  Ros2dDetector all(options);
  ASSERT_TRUE(all.detect(img, kps));
  EXPECT_GT(kps.size(), 2U);
  EXPECT_EQ(static_cast<std::int64_t>(kps.size()), all.stats().second_group);
  for (const auto& kp : kps) EXPECT_GT(kp.response, 0.0F);
}

TEST(Ros2d, ResponsesAreEquation72AndTheSplitIsMsse) {
  Ros2dOptions options;
  options.orientation = false;
  options.equalize = false;
  Ros2dDetector detector(options);
  const cv::Mat img = textured(160, 120, 7);
  std::vector<cv::KeyPoint> kps;
  ASSERT_TRUE(detector.detect(img, kps));
  const Ros2dStats& st = detector.stats();
  ASSERT_GT(kps.size(), 100U);
  EXPECT_EQ(static_cast<std::int64_t>(kps.size()), st.second_group);
  EXPECT_LT(st.second_group, st.residuals);
  // Every feature at or above the transition, strongest first.
  for (std::size_t i = 0; i < kps.size(); ++i) {
    EXPECT_GE(kps[i].response, static_cast<float>(st.threshold));
    if (i > 0) {
      EXPECT_LE(kps[i].response, kps[i - 1].response);
    }
  }
  // The separable form against eq. 7.2's window sum, on octave-0 features of every layer.
  cv::Mat f;
  img.convertTo(f, CV_32F);
  const int r = detector.kernel_radius();
  int checked = 0;
  for (const auto& kp : kps) {
    if ((kp.octave & 0xff) != 0) continue;
    const double sigma = 1.6 * std::pow(2.0, kp.class_id / 3.0);
    const int x = static_cast<int>(std::lround(kp.pt.x));
    const int y = static_cast<int>(std::lround(kp.pt.y));
    const double expected = direct_residual(f, x, y, kernel(sigma, r), r);
    EXPECT_NEAR(static_cast<double>(kp.response), expected, 1e-3 * expected + 0.05) << "at " << x << "," << y;
    if (++checked == 300) break;
  }
  EXPECT_EQ(checked, 300);
}

TEST(Ros2d, MaxFeaturesKeepsTheStrongest) {
  Ros2dOptions options;
  Ros2dDetector all(options);
  options.max_features = 250;
  Ros2dDetector capped(options);
  const cv::Mat img = textured(200, 150, 3);
  std::vector<cv::KeyPoint> a;
  std::vector<cv::KeyPoint> b;
  ASSERT_TRUE(all.detect(img, a));
  ASSERT_TRUE(capped.detect(img, b));
  ASSERT_GT(a.size(), 250U);
  ASSERT_EQ(b.size(), 250U);
  for (std::size_t i = 0; i < b.size(); ++i) {
    EXPECT_EQ(b[i].pt, a[i].pt);
    EXPECT_EQ(b[i].response, a[i].response);
  }
}

TEST(Ros2d, QuarterTurnTurnsPositionsAndOrientations) {
  // Rotating the image by 90° maps each feature onto one of the turned image, its angle +90°.
  Ros2dDetector detector;
  const cv::Mat img = textured(128, 96, 11);  // sides divisible by 8: octave blocks map to blocks
  cv::Mat turned;
  cv::rotate(img, turned, cv::ROTATE_90_CLOCKWISE);
  std::vector<cv::KeyPoint> a;
  std::vector<cv::KeyPoint> b;
  ASSERT_TRUE(detector.detect(img, a));
  ASSERT_TRUE(detector.detect(turned, b));
  ASSERT_GT(a.size(), 200U);
  int matched = 0;
  int angle_ok = 0;
  for (const auto& ka : a) {
    const cv::Point2f expected(static_cast<float>(img.rows) - 1.0F - ka.pt.y, ka.pt.x);
    for (const auto& kb : b) {
      if (kb.octave != ka.octave || std::abs(kb.pt.x - expected.x) > 0.01F || std::abs(kb.pt.y - expected.y) > 0.01F) {
        continue;
      }
      ++matched;
      const float d = std::fmod(kb.angle - ka.angle - 90.0F + 720.0F, 360.0F);
      if (std::min(d, 360.0F - d) < 1.0F) ++angle_ok;
      break;
    }
  }
  EXPECT_GT(matched, static_cast<int>(0.95 * static_cast<double>(a.size())));
  EXPECT_GT(angle_ok, static_cast<int>(0.9 * static_cast<double>(a.size())));
}

TEST(Ros2d, ATeamFindsTheSameFeatures) {
  const cv::Mat img = textured(203, 151, 5);  // odd sides: uneven row chunks
  parallel::ThreadTeam team;
  ASSERT_EQ(team.start(2), "");
  Ros2dDetector alone;
  Ros2dDetector shared;
  shared.use_team(&team);
  std::vector<cv::KeyPoint> a;
  std::vector<cv::KeyPoint> b;
  ASSERT_TRUE(alone.detect(img, a));
  ASSERT_TRUE(shared.detect(img, b));
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 100U);
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].pt, b[i].pt);
    EXPECT_EQ(a[i].angle, b[i].angle);
    EXPECT_EQ(a[i].response, b[i].response);
  }
}

TEST(Ros2d, RefusesWhatItCannotRead) {
  Ros2dDetector detector;
  std::vector<cv::KeyPoint> kps{cv::KeyPoint(1, 1, 1)};
  EXPECT_FALSE(detector.detect(cv::Mat(), kps));
  EXPECT_TRUE(kps.empty());
  EXPECT_FALSE(detector.detect(cv::Mat(64, 64, CV_8UC3, cv::Scalar::all(9)), kps));
  EXPECT_FALSE(detector.detect(cv::Mat(64, 64, CV_16UC1, cv::Scalar::all(9)), kps));
  EXPECT_FALSE(detector.detect(cv::Mat(20, 400, CV_8UC1, cv::Scalar::all(9)), kps));  // too short
  // A flat image has nothing that stands out.
  EXPECT_TRUE(detector.detect(cv::Mat(64, 64, CV_8UC1, cv::Scalar::all(9)), kps));
  EXPECT_TRUE(kps.empty());
}

TEST(Ros2d, OptionsOutOfRangeNameTheField) {
  auto field_of = [](Ros2dOptions o) { return std::string(o.validate()); };
  Ros2dOptions o;
  EXPECT_EQ(field_of(o), "");
  o.octaves = 0;
  EXPECT_EQ(field_of(o), "octaves");
  o = {};
  o.layers = 9;
  EXPECT_EQ(field_of(o), "layers");
  o = {};
  o.min_inlier_fraction = 1.0;
  EXPECT_EQ(field_of(o), "min_inlier_fraction");
  o = {};
  o.border_px = 0;
  EXPECT_EQ(field_of(o), "border_px");
  o = {};
  o.max_features = -1;
  EXPECT_EQ(field_of(o), "max_features");
  try {
    Ros2dDetector bad(o);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_features"), std::string::npos);
  }
}

}  // namespace
}  // namespace rankslam::features
