// ROS2D on real images against OpenCV SIFT (Oxford protocol, test/support/feature_evaluation):
// the thesis' claim of many more features at equal or better repeatability, on graf 1→3, and a
// repeatability floor on a EuRoC frame rotated by 30°. Bounds: the figures measured on
// 2026-12-06 (docs/results.md §11) less a margin.

#include "feature_evaluation.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace rankslam::feature_eval;

const fs::path kData = RANKSLAM_SHARED_DATA;
// ROS2D's repeatability on the first EuRoC V1_01 cam0 frame rotated by 30°, measured, less 0.05.
constexpr double kEurocRot30Floor = 0.90;  // measured 0.957
constexpr double kEurocRot30PlainFloor = 0.85;  // measured 0.902

struct Scores {
  PairScore ros2d;
  PairScore sift;
};

Scores ros2d_and_sift(const cv::Mat& a, const cv::Mat& b, const cv::Matx33d& h) {
  std::vector<Peer> peers = make_peers();
  const auto find = [&](const std::string& name) -> Peer& {
    return *std::find_if(peers.begin(), peers.end(), [&](const Peer& p) { return p.name == name; });
  };
  // Detection alone: descriptors of ROS2D's 10⁵ features and their matching take minutes.
  return {evaluate_pair(find("ROS2D"), a, b, h, false), evaluate_pair(find("SIFT"), a, b, h, false)};
}

/// The figures behind the bounds, for the log.
void report(const char* what, const Scores& s) {
  std::printf("%s: ROS2D n %d rep %.3f plain %.3f | SIFT n %d rep %.3f plain %.3f\n", what, s.ros2d.count,
              s.ros2d.rep.repeatability, s.ros2d.rep_plain.repeatability, s.sift.count, s.sift.rep.repeatability,
              s.sift.rep_plain.repeatability);
}

TEST(Ros2dBench, GrafOneToThreeManyMoreFeaturesAtSiftsRepeatability) {
  const fs::path dir = kData / "oxford" / "graf";
  const cv::Mat img1 = cv::imread((dir / "img1.png").string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat img3 = cv::imread((dir / "img3.png").string(), cv::IMREAD_GRAYSCALE);
  cv::Matx33d h;
  if (img1.empty() || img3.empty() || !read_homography((dir / "H1to3p").string(), h))
    GTEST_SKIP() << "no oxford/graf img1.png, img3.png, H1to3p under " << kData;
  const Scores s = ros2d_and_sift(img1, img3, h);
  report("graf 1→3", s);
  // Measured: ROS2D 70 105 features (mean of the pair), SIFT 3 081 (23×); the claim is 5×.
  EXPECT_GE(s.ros2d.count, 5 * s.sift.count);
  // Measured (normalised overlap): ROS2D 0.88, SIFT 0.71; (plain) 0.72 against 0.24.
  EXPECT_GE(s.ros2d.rep.repeatability, s.sift.rep.repeatability + 0.10);
  EXPECT_GE(s.ros2d.rep_plain.repeatability, s.sift.rep_plain.repeatability + 0.30);
  // SIFT itself in the range published for graf at 40° (a check of the protocol's code).
  EXPECT_GT(s.sift.rep.repeatability, 0.5);
  EXPECT_LT(s.sift.rep.repeatability, 0.9);
}

TEST(Ros2dBench, EurocFrameRotatedThirtyDegreesKeepsRepeatability) {
  const fs::path dir = kData / "euroc" / "V1_01_easy_head" / "mav0" / "cam0" / "data";
  std::vector<std::string> names;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().extension() == ".png") names.push_back(e.path().string());
  if (names.empty()) GTEST_SKIP() << "no EuRoC V1_01_easy_head cam0 frames under " << kData;
  std::sort(names.begin(), names.end());
  const cv::Mat image = cv::imread(names.front(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(image.empty());
  const Transformed t = rotate(image, 30.0);
  const Scores s = ros2d_and_sift(image, t.image, t.h);
  report("EuRoC rotated 30°", s);
  EXPECT_GE(s.ros2d.count, 5 * s.sift.count);
  EXPECT_GE(s.ros2d.rep.repeatability, kEurocRot30Floor);
  EXPECT_GE(s.ros2d.rep_plain.repeatability, kEurocRot30PlainFloor);
}

}  // namespace
