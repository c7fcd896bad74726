// The dense aligner on a textured plane rendered exactly: it recovers the true motion from a
// start centimetres off, and leaves the start alone where it must (other image kinds, no texture,
// a refinement that moves too far).
#include "rankslam/dense/aligner.hpp"

#include "rendered_plane.hpp"

#include <gtest/gtest.h>

namespace rankslam::dense {
namespace {

using test::angle_deg;
using test::motion;

class DenseAlignerTest : public ::testing::Test {
 protected:
  DenseAlignerTest() : camera_(test::plane_camera(), test::kDepthScale) {}

  void prepare(DenseAligner& aligner, const Eigen::Isometry3d& T_ref_cur, bool textured = true, int source = 0) {
    aligner.reserve(reference_);
    aligner.reserve(current_);
    cv::Mat grey, depth;
    test::render_plane(test::plane_camera(), Eigen::Isometry3d::Identity(), textured, grey, depth);
    ASSERT_TRUE(reference_.prepare(grey, depth, static_cast<float>(1.0 / test::kDepthScale), 0.3F, 4.0F, 0));
    test::render_plane(test::plane_camera(), T_ref_cur, textured, grey, depth);
    ASSERT_TRUE(current_.prepare(grey, depth, static_cast<float>(1.0 / test::kDepthScale), 0.3F, 4.0F, source));
  }

  camera::DepthCameraModel camera_;
  DenseFrame reference_;
  DenseFrame current_;
};

TEST_F(DenseAlignerTest, RecoversTheTrueMotionFromAStartCentimetresOff) {
  DenseAligner aligner(camera_, {});
  const Eigen::Isometry3d T_ref_cur = motion(3.0, {0.3, 1.0, 0.2}, {0.04, -0.02, 0.05});
  ASSERT_NO_FATAL_FAILURE(prepare(aligner, T_ref_cur));
  const Eigen::Isometry3d truth = T_ref_cur.inverse();  // T_cur_ref
  Eigen::Isometry3d T = motion(0.8, {1.0, -0.5, 0.3}, {0.012, 0.008, -0.01}) * truth;
  const double start_error_m = (T.translation() - truth.translation()).norm();
  const DenseResult result = aligner.align(reference_, current_, T);
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_LT((T.translation() - truth.translation()).norm(), 0.001) << "start " << start_error_m;
  EXPECT_LT(angle_deg(T.inverse() * truth), 0.05);
  EXPECT_LT(result.final_cost, result.initial_cost);
  EXPECT_GT(result.photometric_inliers, 1000);
  EXPECT_GT(result.iterations, 0);
}

TEST_F(DenseAlignerTest, GreyAloneAlsoRecoversIt) {
  DenseOptions options;
  options.depth_weight = 0.0;
  DenseAligner aligner(camera_, options);
  const Eigen::Isometry3d T_ref_cur = motion(2.0, {1.0, 0.2, -0.4}, {-0.03, 0.02, 0.03});
  ASSERT_NO_FATAL_FAILURE(prepare(aligner, T_ref_cur));
  const Eigen::Isometry3d truth = T_ref_cur.inverse();
  Eigen::Isometry3d T = motion(0.5, {0.0, 1.0, 0.0}, {0.008, 0.0, 0.006}) * truth;
  const DenseResult result = aligner.align(reference_, current_, T);
  ASSERT_TRUE(result.ok) << result.reason;
  EXPECT_EQ(result.depth_inliers, 0);
  EXPECT_LT((T.translation() - truth.translation()).norm(), 0.002);
  EXPECT_LT(angle_deg(T.inverse() * truth), 0.1);
}

TEST_F(DenseAlignerTest, ImagesOfAnotherKindAreNotAligned) {
  DenseAligner aligner(camera_, {});
  const Eigen::Isometry3d T_ref_cur = motion(1.0, {0.0, 1.0, 0.0}, {0.02, 0.0, 0.0});
  ASSERT_NO_FATAL_FAILURE(prepare(aligner, T_ref_cur, true, /*source=*/1));
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const DenseResult result = aligner.align(reference_, current_, T);
  EXPECT_FALSE(result.ok);
  EXPECT_EQ(result.reason, "images of different kinds");
  EXPECT_TRUE(T.isApprox(Eigen::Isometry3d::Identity()));
}

TEST_F(DenseAlignerTest, AnUntexturedPlaneLeavesTheStart) {
  DenseAligner aligner(camera_, {});
  const Eigen::Isometry3d T_ref_cur = motion(1.0, {0.0, 1.0, 0.0}, {0.02, 0.0, 0.0});
  ASSERT_NO_FATAL_FAILURE(prepare(aligner, T_ref_cur, /*textured=*/false));
  const Eigen::Isometry3d start = motion(0.3, {1.0, 0.0, 0.0}, {0.005, 0.0, 0.0}) * T_ref_cur.inverse();
  Eigen::Isometry3d T = start;
  const DenseResult result = aligner.align(reference_, current_, T);
  EXPECT_FALSE(result.ok);
  EXPECT_EQ(result.reason, "too few photometric inliers");
  EXPECT_TRUE(T.isApprox(start));
}

TEST_F(DenseAlignerTest, ARefinementBeyondTheLargestChangeLeavesTheStart) {
  DenseOptions options;
  options.max_change_m = 0.005;
  DenseAligner aligner(camera_, options);
  const Eigen::Isometry3d T_ref_cur = motion(2.0, {0.3, 1.0, 0.2}, {0.03, -0.02, 0.04});
  ASSERT_NO_FATAL_FAILURE(prepare(aligner, T_ref_cur));
  const Eigen::Isometry3d start = motion(0.5, {1.0, -0.5, 0.3}, {0.012, 0.008, -0.01}) * T_ref_cur.inverse();
  Eigen::Isometry3d T = start;
  const DenseResult result = aligner.align(reference_, current_, T);
  EXPECT_FALSE(result.ok);
  EXPECT_EQ(result.reason, "too far from the start");
  EXPECT_TRUE(T.isApprox(start));
}

TEST_F(DenseAlignerTest, FramesOfAnotherSizeAreRefused) {
  DenseAligner aligner(camera_, {});
  aligner.reserve(current_);
  const cv::Mat grey(100, 100, CV_8UC1, cv::Scalar(7));
  const cv::Mat depth(100, 100, CV_16UC1, cv::Scalar(9000));
  EXPECT_FALSE(current_.prepare(grey, depth, 2e-4F, 0.3F, 4.0F, 0));
  EXPECT_FALSE(current_.valid());
}

TEST(DenseOptionsTest, OutOfRangeFieldsAreNamed) {
  DenseOptions options;
  EXPECT_EQ(options.validate(), "");
  options.levels = 6;
  EXPECT_EQ(options.validate(), "levels");
  options = {};
  options.max_depth_m = options.min_depth_m;
  EXPECT_EQ(options.validate(), "max_depth_m");
  options = {};
  options.depth_weight = -1.0;
  EXPECT_EQ(options.validate(), "depth_weight");
  EXPECT_THROW(DenseAligner(camera::DepthCameraModel(test::plane_camera(), test::kDepthScale), options),
               std::invalid_argument);
}

}  // namespace
}  // namespace rankslam::dense
