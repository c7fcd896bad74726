#include "rankslam/eval/trajectory.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/slam/orb_extractor.hpp"
#include "rankslam/slam/orb_frontend.hpp"

#include "allocation_counter.hpp"

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <vector>

namespace {

namespace fs = std::filesystem;
using rankslam::slam::OrbExtractor;
using rankslam::slam::OrbExtractorSettings;

int hamming(const cv::Mat& a, int row_a, const cv::Mat& b, int row_b) {
  int distance = 0;
  for (int i = 0; i < OrbExtractor::kDescriptorBytes; ++i) {
    distance += std::popcount(static_cast<unsigned>(a.at<std::uint8_t>(row_a, i) ^ b.at<std::uint8_t>(row_b, i)));
  }
  return distance;
}

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

/// Smooth random texture: every neighbourhood has corners and a distinct look.
cv::Mat textured_image(int width, int height) {
  cv::Mat noise(height / 4, width / 4, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat image;
  cv::resize(noise, image, cv::Size(width, height), 0, 0, cv::INTER_CUBIC);
  cv::GaussianBlur(image, image, cv::Size(5, 5), 1.0);
  return image;
}

TEST(OrbExtractor, PatternIsDeterministicAndInsideThePatch) {
  const auto& pattern = OrbExtractor::pattern();
  double sum_sq = 0.0;
  for (const OrbExtractor::Test& test : pattern) {
    for (const auto& [x, y] : {std::pair{test.ax, test.ay}, std::pair{test.bx, test.by}}) {
      EXPECT_LE(std::hypot(x, y), static_cast<float>(OrbExtractor::kPatchRadius));
      sum_sq += static_cast<double>(x * x + y * y);
    }
    EXPECT_FALSE(std::lround(test.ax) == std::lround(test.bx) && std::lround(test.ay) == std::lround(test.by));
  }
  // G II: x and y each N(0, 31²/25) (σ = 6.2), truncated at radius 15, so E[x² + y²] is a little
  // below 2 · 6.2² = 76.9.
  const double mean_sq = sum_sq / (2.0 * OrbExtractor::kTests);
  EXPECT_GT(mean_sq, 55.0);
  EXPECT_LT(mean_sq, 80.0);
  // Fixed seed and generator: the pattern is the same on every platform and compiler (stored
  // descriptors depend on it). The first test, as drawn on x86-64 and arm64 alike:
  EXPECT_NEAR(pattern[0].ax, -5.1042F, 1e-3F);
  EXPECT_NEAR(pattern[0].ay, 1.4376F, 1e-3F);
  EXPECT_NEAR(pattern[0].bx, 6.8689F, 1e-3F);
  EXPECT_NEAR(pattern[0].by, 0.2619F, 1e-3F);
}

TEST(OrbExtractor, FastFindsTheCornersOfSquares) {
  // Bright squares on a dark background: FAST-9 fires at their corners and nowhere else.
  cv::Mat image(480, 640, CV_8UC1, cv::Scalar(40));
  std::vector<cv::Point2f> corners;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 4; ++col) {
      const int x0 = 80 + col * 140;
      const int y0 = 70 + row * 130;
      cv::rectangle(image, cv::Rect(x0, y0, 60, 60), cv::Scalar(200), cv::FILLED);
      // Corners between the pixel centres of the square's edge and the background.
      for (const float dx : {-0.5F, 59.5F}) {
        for (const float dy : {-0.5F, 59.5F}) corners.emplace_back(static_cast<float>(x0) + dx, static_cast<float>(y0) + dy);
      }
    }
  }
  OrbExtractorSettings settings;
  settings.levels = 1;
  settings.max_features = 500;
  OrbExtractor extractor(settings);
  ASSERT_TRUE(extractor.extract(image));
  const auto& keypoints = extractor.keypoints();
  std::vector<int> found(corners.size(), 0);
  for (const cv::KeyPoint& keypoint : keypoints) {
    double nearest = 1e9;
    std::size_t which = 0;
    for (std::size_t c = 0; c < corners.size(); ++c) {
      const double d = cv::norm(keypoint.pt - corners[c]);
      if (d < nearest) {
        nearest = d;
        which = c;
      }
    }
    EXPECT_LT(nearest, 3.0) << "keypoint at " << keypoint.pt << " is no corner";
    if (nearest < 3.0) ++found[which];
    EXPECT_GT(keypoint.response, 0.0F) << "a corner's Harris measure is positive";
  }
  for (std::size_t c = 0; c < corners.size(); ++c) EXPECT_GE(found[c], 1) << "corner " << corners[c] << " missed";
  EXPECT_EQ(extractor.descriptors().rows, static_cast<int>(keypoints.size()));

  // All eight levels: coarser levels still place their keypoints on the corners, in level-0
  // pixels, within three level pixels (FAST places a corner on its strongest pixel, not between).
  settings.levels = 8;
  OrbExtractor pyramid(settings);
  ASSERT_TRUE(pyramid.extract(image));
  int coarse = 0;
  for (const cv::KeyPoint& keypoint : pyramid.keypoints()) {
    double nearest = 1e9;
    for (const cv::Point2f& corner : corners) nearest = std::min(nearest, cv::norm(keypoint.pt - corner));
    const double level_px = std::pow(1.2, keypoint.octave);
    EXPECT_LT(nearest, 3.0 * level_px) << "level " << keypoint.octave << " keypoint at " << keypoint.pt;
    if (keypoint.octave > 0) ++coarse;
  }
  EXPECT_GT(coarse, 0);
}

TEST(OrbExtractor, FeatureBudgetFollowsThePyramid) {
  OrbExtractorSettings settings;
  OrbExtractor extractor(settings);
  ASSERT_EQ(extractor.levels(), 8);
  int total = 0;
  for (int l = 0; l < extractor.levels(); ++l) {
    total += extractor.level_budget(l);
    if (l > 0 && l + 1 < extractor.levels()) {
      EXPECT_NEAR(extractor.level_budget(l - 1) / static_cast<double>(extractor.level_budget(l)), 1.2, 0.02);
    }
  }
  EXPECT_EQ(total, settings.max_features);
  const cv::Mat image = textured_image(640, 480);
  ASSERT_TRUE(extractor.extract(image));
  EXPECT_LE(extractor.keypoints().size(), static_cast<std::size_t>(settings.max_features));
  EXPECT_GT(extractor.keypoints().size(), static_cast<std::size_t>(settings.max_features) * 8 / 10);
  std::vector<int> per_level(8, 0);
  for (const cv::KeyPoint& keypoint : extractor.keypoints()) {
    ++per_level[static_cast<std::size_t>(keypoint.octave)];
    EXPECT_GE(keypoint.pt.x, 15.0F);
    EXPECT_GE(keypoint.pt.y, 15.0F);
    EXPECT_LE(keypoint.pt.x, 640.0F - 16.0F);
    EXPECT_LE(keypoint.pt.y, 480.0F - 16.0F);
  }
  for (int l = 0; l < 8; ++l) EXPECT_LE(per_level[static_cast<std::size_t>(l)], extractor.level_budget(l));
}

TEST(OrbExtractor, RejectsWrongImagesAndFollowsANewSize) {
  OrbExtractor extractor(OrbExtractorSettings{});
  EXPECT_FALSE(extractor.extract(cv::Mat()));
  EXPECT_FALSE(extractor.extract(cv::Mat(480, 640, CV_8UC3, cv::Scalar::all(0))));
  EXPECT_TRUE(extractor.keypoints().empty());
  EXPECT_FALSE(extractor.extract(cv::Mat(20, 20, CV_8UC1, cv::Scalar(0)))) << "smaller than one patch";
  EXPECT_TRUE(extractor.extract(textured_image(320, 240)));
  EXPECT_FALSE(extractor.keypoints().empty());
  for (const cv::KeyPoint& keypoint : extractor.keypoints()) {
    EXPECT_LT(keypoint.pt.x, 320.0F);
    EXPECT_LT(keypoint.pt.y, 240.0F);
  }
}

struct RotationOutcome {
  int corresponding = 0;
  double median_distance = 0.0;
  double median_angle_error_deg = 0.0;
};

/// Extracts on `image` and on `rotated` (image turned by `angle_deg` about `centre`, clockwise
/// on screen as y points down), pairs keypoints that land on each other, and compares their
/// descriptors and angles.
RotationOutcome compare_rotated(const cv::Mat& image, const cv::Mat& rotated, const cv::Matx23d& forward, double angle_deg) {
  OrbExtractorSettings settings;
  settings.levels = 1;
  settings.max_features = 500;
  OrbExtractor original_extractor(settings);
  OrbExtractor rotated_extractor(settings);
  EXPECT_TRUE(original_extractor.extract(image));
  EXPECT_TRUE(rotated_extractor.extract(rotated));
  const auto& original = original_extractor.keypoints();
  const auto& turned = rotated_extractor.keypoints();
  RotationOutcome outcome;
  std::vector<double> distances;
  std::vector<double> angle_errors;
  for (std::size_t i = 0; i < original.size(); ++i) {
    const cv::Point2f& p = original[i].pt;
    const cv::Vec2d moved = forward * cv::Vec3d(p.x, p.y, 1.0);
    const cv::Point2f expected(static_cast<float>(moved[0]), static_cast<float>(moved[1]));
    for (std::size_t j = 0; j < turned.size(); ++j) {
      if (cv::norm(turned[j].pt - expected) > 1.0) continue;
      distances.push_back(hamming(original_extractor.descriptors(), static_cast<int>(i), rotated_extractor.descriptors(),
                                  static_cast<int>(j)));
      double error = std::fmod(static_cast<double>(turned[j].angle - original[i].angle) - angle_deg + 720.0, 360.0);
      if (error > 180.0) error = 360.0 - error;
      angle_errors.push_back(error);
      break;
    }
  }
  outcome.corresponding = static_cast<int>(distances.size());
  outcome.median_distance = median(distances);
  outcome.median_angle_error_deg = median(angle_errors);
  return outcome;
}

TEST(OrbExtractor, DescriptorsAreSteeredByTheOrientation) {
  const cv::Mat image = textured_image(480, 480);
  // 90°: exact pixel permutation. cv::rotate clockwise sends (x, y) to (H − 1 − y, x).
  cv::Mat quarter;
  cv::rotate(image, quarter, cv::ROTATE_90_CLOCKWISE);
  const RotationOutcome at90 = compare_rotated(image, quarter, cv::Matx23d(0, -1, 479, 1, 0, 0), 90.0);
  // 30°: resampled, so corners move by interpolation too. getRotationMatrix2D turns
  // counter-clockwise on screen for a positive angle; −30 turns clockwise.
  const cv::Point2f centre(239.5F, 239.5F);
  const cv::Mat forward = cv::getRotationMatrix2D(centre, -30.0, 1.0);
  cv::Mat turned;
  cv::warpAffine(image, turned, forward, image.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT_101);
  const RotationOutcome at30 = compare_rotated(image, turned, cv::Matx23d(forward), 30.0);
  std::printf("90 deg: %d pairs, median distance %.1f bits, median angle error %.2f deg\n", at90.corresponding,
              at90.median_distance, at90.median_angle_error_deg);
  std::printf("30 deg: %d pairs, median distance %.1f bits, median angle error %.2f deg\n", at30.corresponding,
              at30.median_distance, at30.median_angle_error_deg);
  // Unrelated descriptors differ in about 128 of 256 bits.
  EXPECT_GT(at90.corresponding, 100);
  EXPECT_LE(at90.median_distance, 16.0);
  EXPECT_LE(at90.median_angle_error_deg, 2.0);
  EXPECT_GT(at30.corresponding, 100);
  EXPECT_LE(at30.median_distance, 32.0);
  EXPECT_LE(at30.median_angle_error_deg, 3.0);
}

// --- Real frames --------------------------------------------------------------------------

struct TumFrames {
  std::string skip_reason;
  rankslam::hal::Calibration calibration;
  rankslam::eval::Trajectory ground_truth;
  std::vector<double> stamps;
  std::vector<cv::Mat> gray;
  std::vector<cv::Mat> depth;
};

const TumFrames& fr1_rpy_head() {
  static const TumFrames frames = [] {
    TumFrames f;
    const fs::path root = fs::path(RANKSLAM_SHARED_DATA) / "tum" / "fr1_rpy_head";
    if (!fs::is_directory(root)) {
      f.skip_reason = "TUM fr1_rpy_head not found at " + root.string() + " (shared data absent)";
      return f;
    }
    rankslam::replay::Recording recording;
    if (auto error = rankslam::replay::open_recording(root, recording); !error.empty()) {
      f.skip_reason = error;
      return f;
    }
    auto ground_truth = rankslam::eval::read_tum_trajectory(*recording.ground_truth);
    if (!ground_truth) {
      f.skip_reason = ground_truth.error();
      return f;
    }
    f.ground_truth = std::move(ground_truth).value();
    std::sort(f.ground_truth.begin(), f.ground_truth.end(),
              [](const auto& a, const auto& b) { return a.stamp_s < b.stamp_s; });
    f.calibration = recording.calibration;
    for (const auto& entry : recording.frames) {
      cv::Mat bgr = cv::imread((root / entry.rgb_file).string(), cv::IMREAD_COLOR);
      cv::Mat depth = cv::imread((root / entry.depth_file).string(), cv::IMREAD_UNCHANGED);
      if (bgr.empty() || depth.empty()) {
        f.skip_reason = "cannot read " + (root / entry.rgb_file).string();
        return f;
      }
      cv::Mat gray;
      cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
      f.stamps.push_back(entry.rgb_stamp_s);
      f.gray.push_back(gray);
      f.depth.push_back(depth);
    }
    return f;
  }();
  return frames;
}

/// Ground-truth pose at `stamp_s`: interpolated between the motion-capture samples around it.
Eigen::Isometry3d pose_at(const rankslam::eval::Trajectory& trajectory, double stamp_s) {
  const auto after = std::lower_bound(trajectory.begin(), trajectory.end(), stamp_s,
                                      [](const auto& pose, double s) { return pose.stamp_s < s; });
  if (after == trajectory.begin()) return after->T_world_cam;
  if (after == trajectory.end()) return std::prev(after)->T_world_cam;
  const auto before = std::prev(after);
  const double t = (stamp_s - before->stamp_s) / (after->stamp_s - before->stamp_s);
  const Eigen::Quaterniond q = Eigen::Quaterniond(before->T_world_cam.rotation())
                                   .slerp(t, Eigen::Quaterniond(after->T_world_cam.rotation()));
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = q.toRotationMatrix();
  pose.translation() = (1.0 - t) * before->T_world_cam.translation() + t * after->T_world_cam.translation();
  return pose;
}

struct MatchQuality {
  int matches = 0;
  int inliers = 0;
  [[nodiscard]] double ratio() const { return matches > 0 ? static_cast<double>(inliers) / matches : 0.0; }
};

/// Mutual Hamming matches from frame a to frame b; a match is an inlier when the keypoint of a,
/// lifted with its depth and moved by the ground-truth motion, lies within 4 px of b's keypoint
/// (compared as undistorted rays, scaled by fx).
MatchQuality match_quality(const TumFrames& frames, const rankslam::camera::DepthCameraModel& camera, int a, int b,
                           const std::vector<cv::KeyPoint>& keypoints_a, const cv::Mat& descriptors_a,
                           const std::vector<cv::KeyPoint>& keypoints_b, const cv::Mat& descriptors_b) {
  rankslam::slam::MutualHammingMatcher matcher;
  std::vector<rankslam::slam::FeatureMatch> matches;
  matcher.match(descriptors_a, descriptors_b, 64, matches);
  const Eigen::Isometry3d T_b_a = pose_at(frames.ground_truth, frames.stamps[static_cast<std::size_t>(b)]).inverse() *
                                  pose_at(frames.ground_truth, frames.stamps[static_cast<std::size_t>(a)]);
  const cv::Mat& depth = frames.depth[static_cast<std::size_t>(a)];
  MatchQuality quality;
  for (const auto& match : matches) {
    const cv::Point2f& pa = keypoints_a[match.source].pt;
    const cv::Point2f& pb = keypoints_b[match.target].pt;
    const int u = static_cast<int>(std::lround(pa.x));
    const int v = static_cast<int>(std::lround(pa.y));
    const unsigned short raw = depth.at<unsigned short>(v, u);
    if (raw == 0) continue;  // only matches that can be checked count
    ++quality.matches;
    const Eigen::Vector3d point_a = camera.back_project(u, v, camera.metres(raw)).cast<double>();
    const Eigen::Vector3d point_b = T_b_a * point_a;
    if (point_b.z() <= 0.0) continue;
    const Eigen::Vector2f ray_b = camera.ray(pb.x, pb.y);
    const double error_px = camera.calibration().fx * (point_b.head<2>() / point_b.z() - ray_b.cast<double>()).norm();
    if (error_px < 4.0) ++quality.inliers;
  }
  return quality;
}

TEST(OrbExtractor, MatchesRealFramesAsWellAsOpenCvOrb) {
  const TumFrames& frames = fr1_rpy_head();
  if (!frames.skip_reason.empty()) GTEST_SKIP() << frames.skip_reason;
  const rankslam::camera::DepthCameraModel camera(frames.calibration.rgb, frames.calibration.depth_scale);
  OrbExtractorSettings settings;  // the SLAM defaults: 1000 features, 1.2, 8 levels, FAST 20
  OrbExtractor extractor_a(settings);
  OrbExtractor extractor_b(settings);
  // OpenCV's ORB as the SLAM loop configured it: the oracle.
  cv::Ptr<cv::ORB> orb = cv::ORB::create(1000, 1.2F, 8, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31, 20);
  MatchQuality ours;
  MatchQuality opencv;
  const int n = static_cast<int>(frames.gray.size());
  for (int a = 0; a + 3 < n; a += 8) {
    for (const int gap : {1, 3}) {
      const int b = a + gap;
      ASSERT_TRUE(extractor_a.extract(frames.gray[static_cast<std::size_t>(a)]));
      ASSERT_TRUE(extractor_b.extract(frames.gray[static_cast<std::size_t>(b)]));
      const MatchQuality q = match_quality(frames, camera, a, b, extractor_a.keypoints(), extractor_a.descriptors(),
                                           extractor_b.keypoints(), extractor_b.descriptors());
      std::vector<cv::KeyPoint> keypoints_a;
      std::vector<cv::KeyPoint> keypoints_b;
      cv::Mat descriptors_a;
      cv::Mat descriptors_b;
      orb->detectAndCompute(frames.gray[static_cast<std::size_t>(a)], cv::noArray(), keypoints_a, descriptors_a);
      orb->detectAndCompute(frames.gray[static_cast<std::size_t>(b)], cv::noArray(), keypoints_b, descriptors_b);
      const MatchQuality reference =
          match_quality(frames, camera, a, b, keypoints_a, descriptors_a, keypoints_b, descriptors_b);
      ours.matches += q.matches;
      ours.inliers += q.inliers;
      opencv.matches += reference.matches;
      opencv.inliers += reference.inliers;
    }
  }
  std::printf("fr1_rpy_head pairs: OrbExtractor %d inliers of %d matches (%.3f), cv::ORB %d of %d (%.3f)\n",
              ours.inliers, ours.matches, ours.ratio(), opencv.inliers, opencv.matches, opencv.ratio());
  EXPECT_GE(ours.ratio(), 0.9 * opencv.ratio());
  EXPECT_GE(ours.inliers, 0.8 * opencv.inliers);
}

TEST(OrbExtractor, DescribingItsOwnKeypointsReproducesItsDescriptors) {
  // describe() on extract()'s keypoints (size 31 px at level 0) finds their levels, orientations
  // and descriptors again.
  const TumFrames& frames = fr1_rpy_head();
  if (!frames.skip_reason.empty()) GTEST_SKIP() << frames.skip_reason;
  OrbExtractor extractor(OrbExtractorSettings{});
  ASSERT_TRUE(extractor.extract(frames.gray[3]));
  const std::vector<cv::KeyPoint> own = extractor.keypoints();
  const cv::Mat descriptors = extractor.descriptors().clone();
  ASSERT_GT(own.size(), 500U);
  ASSERT_TRUE(extractor.describe(frames.gray[3], own, 2.0F * OrbExtractor::kPatchRadius + 1.0F));
  ASSERT_EQ(extractor.keypoints().size(), own.size());
  for (std::size_t i = 0; i < own.size(); ++i) {
    const cv::KeyPoint& again = extractor.keypoints()[i];
    EXPECT_EQ(again.octave, own[i].octave);
    EXPECT_FLOAT_EQ(again.angle, own[i].angle);
    EXPECT_EQ(cv::norm(extractor.descriptors().row(static_cast<int>(i)), descriptors.row(static_cast<int>(i)),
                       cv::NORM_HAMMING),
              0.0);
  }
}

TEST(OrbExtractor, ExtractsRealFramesWithoutAllocating) {
  const TumFrames& frames = fr1_rpy_head();
  if (!frames.skip_reason.empty()) GTEST_SKIP() << frames.skip_reason;
  ASSERT_GE(frames.gray.size(), 51U);
  OrbExtractor extractor(OrbExtractorSettings{});
  ASSERT_TRUE(extractor.extract(frames.gray[0]));  // warm-up
  long allocations = 0;
  std::size_t features = 0;
  {
    const rankslam::test_support::CountAllocations count;
    for (std::size_t i = 1; i <= 50; ++i) {
      if (!extractor.extract(frames.gray[i])) break;
      features += extractor.keypoints().size();
    }
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0) << "malloc counted: " << rankslam::test_support::counts_malloc();
  EXPECT_GT(features, 50U * 900U);

  // The whole photometric front-end: extraction, depth look-up, descriptor copies.
  rankslam::slam::SlamConfig config;
  const rankslam::camera::DepthCameraModel camera(frames.calibration.rgb, frames.calibration.depth_scale);
  rankslam::slam::OrbFrontend frontend(config, camera);
  rankslam::slam::PhotometricFeatures photometric;
  photometric.reserve(static_cast<std::size_t>(config.orb_features) * 2);
  frontend.extract(frames.gray[0], frames.depth[0], photometric);
  std::size_t with_depth = 0;
  {
    const rankslam::test_support::CountAllocations count;
    for (std::size_t i = 1; i <= 50; ++i) {
      frontend.extract(frames.gray[i], frames.depth[i], photometric);
      with_depth += photometric.size();
    }
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(with_depth, 50U * 500U);

  // With ROS2D's keypoints (docs/methods.md §15) in place of FAST's.
  config.ros2d_keypoints = 1;
  rankslam::slam::OrbFrontend ros2d_frontend(config, camera);
  ros2d_frontend.extract(frames.gray[0], frames.depth[0], photometric);
  std::size_t ros2d_with_depth = 0;
  {
    const rankslam::test_support::CountAllocations count;
    for (std::size_t i = 1; i <= 50; ++i) {
      ros2d_frontend.extract(frames.gray[i], frames.depth[i], photometric);
      ros2d_with_depth += photometric.size();
      EXPECT_LE(photometric.size(), static_cast<std::size_t>(config.orb_features));
    }
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(ros2d_with_depth, 50U * 500U);

  // One front-end serves colour and infrared images, each kind with its own FAST threshold, and
  // switching kinds allocates nothing.
  config.ros2d_keypoints = 0;
  config.orb_fast_threshold = 60;
  config.ir_orb_fast_threshold = 5;
  rankslam::slam::OrbFrontend both(config, camera);
  both.extract(frames.gray[0], frames.depth[0], photometric, rankslam::slam::ImageSource::kColour);
  const std::size_t colour = photometric.size();
  {
    const rankslam::test_support::CountAllocations count;
    both.extract(frames.gray[0], frames.depth[0], photometric, rankslam::slam::ImageSource::kInfrared);
    const std::size_t infrared = photometric.size();
    both.extract(frames.gray[0], frames.depth[0], photometric, rankslam::slam::ImageSource::kColour);
    allocations = count.allocations();
    EXPECT_GT(infrared, 2 * colour) << "the infrared threshold (5) finds more corners than the colour one (60)";
  }
  EXPECT_EQ(photometric.size(), colour);
  EXPECT_EQ(allocations, 0);
}

}  // namespace

TEST(OrbExtractor, AnImagesFeaturesDoNotDependOnTheImageBefore) {
  const TumFrames& frames = fr1_rpy_head();
  if (!frames.skip_reason.empty()) GTEST_SKIP() << frames.skip_reason;
  ASSERT_GE(frames.gray.size(), 11U);
  OrbExtractor fresh(OrbExtractorSettings{});
  ASSERT_TRUE(fresh.extract(frames.gray[10]));
  OrbExtractor used(OrbExtractorSettings{});
  cv::Mat dark;
  frames.gray[0].convertTo(dark, -1, 0.2, 3.0);
  used.set_fast_threshold(5);
  ASSERT_TRUE(used.extract(dark));
  used.set_fast_threshold(OrbExtractorSettings{}.fast_threshold);
  ASSERT_TRUE(used.extract(frames.gray[10]));
  ASSERT_EQ(used.keypoints().size(), fresh.keypoints().size());
  int differing = 0;
  for (std::size_t i = 0; i < fresh.keypoints().size(); ++i) {
    const cv::KeyPoint& a = fresh.keypoints()[i];
    const cv::KeyPoint& b = used.keypoints()[i];
    const bool same = a.pt == b.pt && a.angle == b.angle && a.octave == b.octave && a.response == b.response &&
                      cv::norm(fresh.descriptors().row(static_cast<int>(i)), used.descriptors().row(static_cast<int>(i)),
                               cv::NORM_HAMMING) == 0.0;
    differing += same ? 0 : 1;
  }
  EXPECT_EQ(differing, 0);
}
