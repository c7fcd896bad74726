// Sensor models: Kinect depth noise growing with z², range and grazing-angle limits, a dark
// colour image and an IR image with projector speckle over the scene's texture.
#include "sim_test_support.hpp"

#include "rankslam/sim/scene.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>

namespace rankslam::sim {
namespace {

using testing::image_of;
using testing::TempDir;

TEST(SimDepthNoise, GrowsWithTheSquareOfDepthAndIsQuantisedInDisparity) {
  // The corridor seen down a straight: floor and walls from 0.7 m to beyond the range.
  TempDir exact("exact");
  TempDir noisy("noisy");
  auto options = testing::options_for("corridor-loop", exact.path(), 2);
  options.first_frame = 200;
  options.sensor_noise = false;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.out_dir = noisy.path();
  options.sensor_noise = true;
  ASSERT_EQ(simulate_recording(options, nullptr), "");

  // Error of the noisy depth against the exact depth of the same pixel, divided by z², binned
  // by depth.
  struct Bin {
    double lo, hi;
    double sum = 0, sum2 = 0, raw_sum2 = 0;
    int n = 0;
  };
  std::vector<Bin> bins = {{0.8, 1.5}, {1.5, 2.5}, {2.5, 3.5}, {3.5, 4.4}};
  int dropped = 0;
  int both = 0;
  int off_grid = 0;
  for (std::size_t f = 0; f < 2; ++f) {
    const cv::Mat a = image_of(exact.path(), "depth.txt", f, cv::IMREAD_UNCHANGED);
    const cv::Mat b = image_of(noisy.path(), "depth.txt", f, cv::IMREAD_UNCHANGED);
    for (int v = 0; v < a.rows; ++v) {
      for (int u = 0; u < a.cols; ++u) {
        const double z = a.at<std::uint16_t>(v, u) / 5000.0;
        const double zn = b.at<std::uint16_t>(v, u) / 5000.0;
        if (z == 0.0) continue;
        if (zn == 0.0) {
          ++dropped;
          continue;
        }
        ++both;
        // Disparity is quantised to 1/8 px: 8·f·b/z lands on integers (up to the 0.2 mm unit).
        const double steps = 8.0 * 580.0 * 0.075 / zn;
        const double unit = 8.0 * 580.0 * 0.075 / (zn * zn) * 1e-4;
        off_grid += std::abs(steps - std::round(steps)) > unit + 1e-6 ? 1 : 0;
        for (auto& bin : bins) {
          if (z >= bin.lo && z < bin.hi) {
            const double e = (zn - z) / (z * z);
            bin.sum += e;
            bin.sum2 += e * e;
            bin.raw_sum2 += (zn - z) * (zn - z);
            ++bin.n;
          }
        }
      }
    }
  }
  EXPECT_EQ(off_grid, 0) << "depths off the 1/8 px disparity grid";
  EXPECT_LT(static_cast<double>(dropped) / (dropped + both), 0.1) << "drop-outs should be few";
  double previous_rms = 0.0;
  for (const auto& bin : bins) {
    ASSERT_GT(bin.n, 2000) << "depth bin " << bin.lo << ".." << bin.hi;
    const double mean = bin.sum / bin.n;
    const double sigma = std::sqrt(bin.sum2 / bin.n - mean * mean);
    // σ_z / z² is constant: 1.425e-3 from disparity noise, about 1.65e-3 with the 1/8 px
    // quantisation.
    EXPECT_GT(sigma, 1.3e-3) << "bin " << bin.lo;
    EXPECT_LT(sigma, 2.1e-3) << "bin " << bin.lo;
    EXPECT_LT(std::abs(mean), 0.2 * sigma) << "bin " << bin.lo << ": depth noise must be unbiased";
    const double rms = std::sqrt(bin.raw_sum2 / bin.n);
    EXPECT_GT(rms, 1.5 * previous_rms) << "bin " << bin.lo;
    previous_rms = rms;
  }
}

TEST(SimDepthRange, NoDepthBeyondTheSensorRangeOrAtGrazingAngles) {
  // Noise-free, so the same pixel has the same depth in both recordings when it is measured.
  TempDir normal("range_normal");
  TempDir extended("range_extended");
  TempDir near_cut("range_near");
  auto options = testing::options_for("corridor-loop", normal.path(), 1);
  options.first_frame = 200;  // driving down the 6 m straight: the far wall is out of range
  options.sensor_noise = false;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.out_dir = extended.path();
  options.max_depth_m = 12.0;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.out_dir = near_cut.path();
  options.max_depth_m = 4.5;
  options.min_depth_m = 2.0;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  const cv::Mat a = image_of(normal.path(), "depth.txt", 0, cv::IMREAD_UNCHANGED);
  const cv::Mat b = image_of(extended.path(), "depth.txt", 0, cv::IMREAD_UNCHANGED);
  const cv::Mat c = image_of(near_cut.path(), "depth.txt", 0, cv::IMREAD_UNCHANGED);
  int far = 0;
  int in_range = 0;
  int near = 0;
  for (int v = 0; v < a.rows; ++v) {
    for (int u = 0; u < a.cols; ++u) {
      const double z = b.at<std::uint16_t>(v, u) / 5000.0;
      const auto za = a.at<std::uint16_t>(v, u);
      const auto zc = c.at<std::uint16_t>(v, u);
      if (z > 4.5) {
        ++far;
        EXPECT_EQ(za, 0) << "pixel " << u << "," << v << " at " << z << " m";
      } else if (z > 0.0) {
        ++in_range;
        EXPECT_EQ(za, b.at<std::uint16_t>(v, u));
      }
      if (z > 0.0 && z < 2.0) {
        ++near;
        EXPECT_EQ(zc, 0);
      }
    }
  }
  EXPECT_GT(far, 5000) << "the view should reach past 4.5 m";
  EXPECT_GT(in_range, 100000);
  EXPECT_GT(near, 5000);

  // Every measured pixel sees its surface at more than ~85° from grazing.
  std::string error;
  const auto scene = make_scene("corridor-loop", 1, &error);
  ASSERT_TRUE(scene) << error;
  const hal::Calibration calibration = testing::read_calibration(normal / "calibration.yaml");
  const auto gt = testing::read_groundtruth(normal / "groundtruth.txt");
  ASSERT_EQ(gt.size(), 1U);
  int measured = 0;
  for (int v = 0; v < a.rows; v += 2) {
    for (int u = 0; u < a.cols; u += 2) {
      const auto raw = a.at<std::uint16_t>(v, u);
      if (raw == 0) continue;
      const Eigen::Vector3d p_cam = testing::back_project(calibration.rgb, u, v, raw / 5000.0);
      const Eigen::Vector3d p = gt[0].T * p_cam;
      // The surface the point is on; at an edge between two faces take the better-lit one.
      const Eigen::Vector3d ray = gt[0].T.linear() * p_cam.normalized();
      double best_cos = -1.0;
      for (const auto& quad : scene->surfaces) {
        if (quad.distance_m(p) < 2e-3) best_cos = std::max(best_cos, std::abs(ray.dot(quad.normal())));
      }
      EXPECT_GE(best_cos, 0.075) << "pixel " << u << "," << v;
      ++measured;
    }
  }
  EXPECT_GT(measured, 20000);
}

// Laplacian of Gaussian, a band-pass that keeps texture and drops both flat shading and
// single-pixel noise.
cv::Mat band_pass(const cv::Mat& gray) {
  cv::Mat f;
  cv::Mat blurred;
  cv::Mat log;
  gray.convertTo(f, CV_32F);
  cv::GaussianBlur(f, blurred, cv::Size(0, 0), 2.0);
  cv::Laplacian(blurred, log, CV_32F);
  return log;
}

double correlation(const cv::Mat& a, const cv::Mat& b) {
  cv::Scalar mean_a, sd_a, mean_b, sd_b;
  cv::meanStdDev(a, mean_a, sd_a);
  cv::meanStdDev(b, mean_b, sd_b);
  const double covariance = cv::mean((a - mean_a[0]).mul(b - mean_b[0]))[0];
  return covariance / (sd_a[0] * sd_b[0]);
}

TEST(SimDarkOffice, ColourIsDarkAndIrShowsSpeckleOverTheScenesTexture) {
  TempDir dark("dark");
  TempDir lit("lit");
  auto options = testing::options_for("dark-office", dark.path(), 2);
  options.seed = 3;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.scene = "office";
  options.out_dir = lit.path();
  options.sensor_noise = false;
  ASSERT_EQ(simulate_recording(options, nullptr), "");

  for (std::size_t f = 0; f < 2; ++f) {
    // Colour: nearly black, what little there is mostly noise.
    const cv::Mat rgb = image_of(dark.path(), "rgb.txt", f, cv::IMREAD_GRAYSCALE);
    cv::Scalar mean, sd;
    cv::meanStdDev(rgb, mean, sd);
    EXPECT_LT(mean[0], 15.0);
    EXPECT_GT(sd[0], 1.5);
    cv::Mat smooth;
    cv::medianBlur(rgb, smooth, 5);
    cv::Mat residual;
    cv::absdiff(rgb, smooth, residual);
    EXPECT_GT(cv::mean(residual)[0], 1.0) << "sensor noise should dominate the dark image";

    // IR: well exposed, with speckle dots that a 3×3 opening removes.
    const cv::Mat ir = image_of(dark.path(), "ir.txt", f, cv::IMREAD_UNCHANGED);
    ASSERT_EQ(ir.type(), CV_8UC1);
    const double ir_mean = cv::mean(ir)[0];
    EXPECT_GT(ir_mean, 40.0);
    EXPECT_LT(ir_mean, 200.0);
    cv::Mat opened;
    cv::morphologyEx(ir, opened, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, {3, 3}));
    cv::Mat dots = (ir - opened) > 25;
    EXPECT_GT(cv::countNonZero(dots), static_cast<int>(0.05 * static_cast<double>(ir.total())));
    // The product's IR pre-processing (opening + 5×5 median) reveals the texture: it then
    // matches the lit scene's texture far better than the raw IR does.
    cv::Mat filtered;
    cv::medianBlur(opened, filtered, 5);
    const cv::Mat reference = band_pass(image_of(lit.path(), "rgb.txt", f, cv::IMREAD_GRAYSCALE));
    const double raw_match = correlation(band_pass(ir), reference);
    const double filtered_match = correlation(band_pass(filtered), reference);
    EXPECT_GT(filtered_match, 0.4) << "IR should carry the scene's texture";
    EXPECT_GT(filtered_match, raw_match + 0.1) << "speckle should hide part of it";
  }

  // The dots are fixed in the projector: they move across the image with the camera, so the
  // same pixel's dots differ between frames while the scene barely moves.
  const cv::Mat ir0 = image_of(dark.path(), "ir.txt", 0, cv::IMREAD_UNCHANGED);
  const cv::Mat ir1 = image_of(dark.path(), "ir.txt", 1, cv::IMREAD_UNCHANGED);
  EXPECT_GT(cv::norm(ir0, ir1, cv::NORM_L1) / static_cast<double>(ir0.total()), 3.0);
}

}  // namespace
}  // namespace rankslam::sim
