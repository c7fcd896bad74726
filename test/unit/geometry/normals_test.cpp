// Normal quality: the organised (block-mean) PCA normals against PCA over every dense neighbour
// within the same radius (a k-d tree radius search, as PCL's NormalEstimation with the dense
// cloud as search surface would do).
//
// "Quality" is measured against the geometry: simulated frames are rendered twice, with and
// without sensor noise, and both normal estimates on the noisy frame are compared with the
// dense PCA of the noise-free frame. On real frames, where no noise-free twin exists, the
// agreement with the dense PCA is bounded.

#include <algorithm>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>
#include <nanoflann.hpp>

#include "rankslam/geometry/cloud.hpp"
#include "rankslam/parallel/cpu_features.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "test_data.hpp"

namespace rankslam::geometry {
namespace {

struct Dense {
  std::vector<Eigen::Vector3f> pts;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return pts.size(); }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t d) const { return pts[i][static_cast<Eigen::Index>(d)]; }
  template <class B>
  bool kdtree_get_bbox(B& /*bb*/) const { return false; }
};
using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Dense>, Dense, 3>;

class DensePca {
 public:
  DensePca(const cv::Mat& depth, const camera::DepthCameraModel& camera, float max_m) {
    for (int v = 0; v < depth.rows; ++v) {
      for (int u = 0; u < depth.cols; ++u) {
        const auto raw = depth.at<std::uint16_t>(v, u);
        if (raw == 0 || camera.metres(raw) > max_m) continue;
        dense_.pts.push_back(camera.back_project(u, v, camera.metres(raw)));
      }
    }
    tree_ = std::make_unique<Tree>(3, dense_, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    tree_->buildIndex();
  }
  [[nodiscard]] Eigen::Vector3d normal(const Eigen::Vector3f& center, float radius) const {
    std::vector<std::pair<std::uint32_t, float>> found;
    nanoflann::SearchParams params;
    tree_->radiusSearch(center.data(), radius * radius, found, params);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& f : found) mean += dense_.pts[f.first].cast<double>();
    mean /= static_cast<double>(std::max<std::size_t>(found.size(), 1));
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& f : found) {
      const Eigen::Vector3d d = dense_.pts[f.first].cast<double>() - mean;
      cov += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(cov);
    Eigen::Vector3d n = solver.eigenvectors().col(0);
    return n.dot(center.cast<double>()) > 0.0 ? Eigen::Vector3d(-n) : n;
  }

 private:
  Dense dense_;
  std::unique_ptr<Tree> tree_;
};

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.dot(b), -1.0, 1.0)) * 180.0 / M_PI;
}

struct Quantiles {
  double median = 0.0;
  double p90 = 0.0;
};

Quantiles quantiles(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return {v[v.size() / 2], v[v.size() * 9 / 10]};
}

TEST(Normals, AsCloseToTheNoiseFreeGeometryAsDensePca) {
  for (const std::string scene : {"zigzag-plain", "office"}) {
    hal::Calibration calibration;
    std::string error;
    const auto noisy = testing::simulated_depth_frames(scene, 30, 1, true, calibration, error);
    ASSERT_EQ(error, "");
    const auto clean = testing::simulated_depth_frames(scene, 30, 1, false, calibration, error);
    ASSERT_EQ(error, "");
    ASSERT_EQ(noisy.size(), 1U);
    ASSERT_EQ(clean.size(), 1U);
    const camera::DepthCameraModel camera(calibration.rgb, calibration.depth_scale);
    GeometryConfig config;
    CloudPreprocessor preprocessor;
    ASSERT_EQ(preprocessor.configure(camera, config, 16384), "");
    SampledCloud cloud = preprocessor.make_cloud();
    ASSERT_EQ(preprocessor.process(noisy[0], cloud), GeometryStatus::kOk);
    const DensePca noisy_pca(noisy[0], camera, 4.0F);
    const DensePca clean_pca(clean[0], camera, 4.0F);
    std::vector<double> organised_error;
    std::vector<double> dense_error;
    for (int i = 0; i < cloud.size; ++i) {
      const Eigen::Vector3f& c = cloud.points[static_cast<std::size_t>(i)];
      const Eigen::Vector3d truth = clean_pca.normal(c, cloud.normal_radius_m);
      organised_error.push_back(angle_deg(cloud.normals[static_cast<std::size_t>(i)].cast<double>(), truth));
      dense_error.push_back(angle_deg(noisy_pca.normal(c, cloud.normal_radius_m), truth));
    }
    const Quantiles organised = quantiles(organised_error);
    const Quantiles dense = quantiles(dense_error);
    std::printf("%s: error vs noise-free dense PCA, organised median %.2f° p90 %.2f°, dense median %.2f° p90 %.2f°\n",
                scene.c_str(), organised.median, organised.p90, dense.median, dense.p90);
    EXPECT_LE(organised.median, dense.median + 0.1) << scene;
    EXPECT_LE(organised.p90, dense.p90 + 0.5) << scene;
  }
}

TEST(Normals, AgreeWithDensePcaOnRealFrames) {
  hal::Calibration calibration;
  const auto frames = testing::tum_depth_frames("fr1_desk_9", 2, calibration);
  if (frames.empty()) GTEST_SKIP() << "shared data (RANKSLAM_SHARED_DATA/tum/fr1_desk_9) is absent";
  const camera::DepthCameraModel camera(calibration.rgb, calibration.depth_scale);
  GeometryConfig config;
  CloudPreprocessor preprocessor;
  ASSERT_EQ(preprocessor.configure(camera, config, 16384), "");
  SampledCloud cloud = preprocessor.make_cloud();
  for (const cv::Mat& depth : frames) {
    ASSERT_EQ(preprocessor.process(depth, cloud), GeometryStatus::kOk);
    const DensePca pca(depth, camera, 4.0F);
    std::vector<double> error;
    for (int i = 0; i < cloud.size; ++i) {
      error.push_back(angle_deg(cloud.normals[static_cast<std::size_t>(i)].cast<double>(),
                                pca.normal(cloud.points[static_cast<std::size_t>(i)], cloud.normal_radius_m)));
    }
    const Quantiles q = quantiles(error);
    std::printf("fr1_desk_9: organised vs dense PCA median %.2f° p90 %.2f°\n", q.median, q.p90);
    EXPECT_LE(q.median, 1.5);
    EXPECT_LE(q.p90, 8.0);
  }
}

// The vector kernel's window sums (Highway, where the CPU has a vector target) against the
// portable loop: the same normals up to float summation order and fused multiply-adds.
TEST(Normals, PortableAndVectorWindowSumsAgree) {
  if (!parallel::vector_kernels_enabled()) GTEST_SKIP() << "no vector target: only the portable loop runs here";
  hal::Calibration calibration;
  std::string error;
  const auto frames = testing::simulated_depth_frames("office", 30, 1, true, calibration, error);
  ASSERT_EQ(error, "");
  ASSERT_EQ(frames.size(), 1U);
  const camera::DepthCameraModel camera(calibration.rgb, calibration.depth_scale);
  GeometryConfig config;
  CloudPreprocessor preprocessor;
  ASSERT_EQ(preprocessor.configure(camera, config, 16384), "");
  SampledCloud cloud = preprocessor.make_cloud();
  ASSERT_EQ(preprocessor.process(frames[0], cloud), GeometryStatus::kOk);
  const auto fx = static_cast<float>(calibration.rgb.fx);
  std::vector<double> difference;
  for (int i = 0; i < cloud.size; ++i) {
    const auto k = static_cast<std::size_t>(i);
    Eigen::Vector3f best = Eigen::Vector3f::Zero();
    Eigen::Vector3f portable = Eigen::Vector3f::Zero();
    const int used_best = organised_normal(preprocessor.blocks(), fx, cloud.points[k], cloud.pixels[k],
                                           cloud.normal_radius_m, config.normal_samples_per_axis, best,
                                           nullptr, true);
    const int used_portable = organised_normal(preprocessor.blocks(), fx, cloud.points[k], cloud.pixels[k],
                                               cloud.normal_radius_m, config.normal_samples_per_axis,
                                               portable, nullptr, false);
    EXPECT_NEAR(used_best, used_portable, 1) << i;
    difference.push_back(angle_deg(best.cast<double>(), portable.cast<double>()));
  }
  std::sort(difference.begin(), difference.end());
  std::printf("%s vs portable window sums: %zu normals, median %.2g°, max %.2g°\n",
              parallel::vector_target().c_str(), difference.size(),
              difference[difference.size() / 2], difference.back());
  EXPECT_LE(difference.back(), 0.1);
}

}  // namespace
}  // namespace rankslam::geometry
