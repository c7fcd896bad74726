// Exercises each sysroot library once, so a missing or mislinked arm64 library shows up as a
// failing test under the emulator rather than on the robot.
#include <CLI/CLI.hpp>
#include <Eigen/Dense>
#include <OpenNI.h>
#include <benchmark/benchmark.h>
#include <ceres/ceres.h>
#include <gtest/gtest.h>
#include <nanoflann.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <systemd/sd-daemon.h>
#include <yaml-cpp/yaml.h>

#include <array>
#include <cstdlib>
#include <vector>

namespace {

struct LineResidual {
  double x;
  double y;
  template <typename T>
  bool operator()(const T* const slope, const T* const offset, T* residual) const {
    residual[0] = T(y) - (slope[0] * T(x) + offset[0]);
    return true;
  }
};

struct PointCloud {
  std::vector<std::array<double, 2>> points;
  size_t kdtree_get_point_count() const { return points.size(); }
  double kdtree_get_pt(size_t index, size_t dim) const { return points[index][dim]; }
  template <class Box>
  bool kdtree_get_bbox(Box&) const { return false; }
};

}  // namespace

TEST(SysrootCheck, EigenSolves) {
  Eigen::Matrix3d a;
  a << 4, 1, 0, 1, 3, 1, 0, 1, 2;
  const Eigen::Vector3d x = a.ldlt().solve(Eigen::Vector3d(1, 2, 3));
  EXPECT_NEAR((a * x - Eigen::Vector3d(1, 2, 3)).norm(), 0.0, 1e-12);
}

TEST(SysrootCheck, OpenCvModules) {
  cv::Mat image(128, 128, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(image, image, cv::Size(5, 5), 1.5);
  std::vector<uchar> png;
  ASSERT_TRUE(cv::imencode(".png", image, png));
  const cv::Mat decoded = cv::imdecode(png, cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(cv::norm(decoded, image, cv::NORM_INF), 0.0);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  cv::ORB::create(100)->detectAndCompute(decoded, cv::noArray(), keypoints, descriptors);
  EXPECT_GT(keypoints.size(), 10u);
  EXPECT_EQ(descriptors.rows, static_cast<int>(keypoints.size()));
  const cv::Mat rotation = cv::Mat::eye(3, 3, CV_64F);
  cv::Mat rvec;
  cv::Rodrigues(rotation, rvec);
  EXPECT_EQ(cv::norm(rvec), 0.0);
}

TEST(SysrootCheck, CeresFitsLine) {
  double slope = 0.0;
  double offset = 0.0;
  ceres::Problem problem;
  for (int i = 0; i < 20; ++i) {
    const double x = i;
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<LineResidual, 1, 1, 1>(
                                 new LineResidual{x, 2.0 * x + 1.0}),
                             nullptr, &slope, &offset);
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  EXPECT_NEAR(slope, 2.0, 1e-9);
  EXPECT_NEAR(offset, 1.0, 1e-9);
}

TEST(SysrootCheck, YamlAndCli) {
  const YAML::Node node = YAML::Load("range_m: 4.5");
  EXPECT_EQ(node["range_m"].as<double>(), 4.5);
  CLI::App app;
  int count = 0;
  app.add_option("--count", count);
  const char* argv[] = {"check", "--count", "3"};
  app.parse(3, argv);
  EXPECT_EQ(count, 3);
}

TEST(SysrootCheck, NanoflannFindsNearest) {
  PointCloud cloud{{{0.0, 0.0}, {1.0, 1.0}, {5.0, 5.0}}};
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<
      nanoflann::L2_Simple_Adaptor<double, PointCloud>, PointCloud, 2>;
  Tree tree(2, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  tree.buildIndex();
  const double query[2] = {4.0, 4.5};
  unsigned int index = 0;
  double distance_sq = 0.0;
  tree.knnSearch(query, 1, &index, &distance_sq);
  EXPECT_EQ(index, 2u);
}

TEST(SysrootCheck, OpenNi2Initialises) {
  // No camera is attached here; initialising loads the drivers from the sysroot and returns.
  // Under qemu this needs the sysroot's OpenNI.ini to name the drivers by their host path.
  EXPECT_EQ(openni::OpenNI::initialize(), openni::STATUS_OK) << openni::OpenNI::getExtendedError();
  openni::Array<openni::DeviceInfo> devices;
  openni::OpenNI::enumerateDevices(&devices);
  EXPECT_GE(devices.getSize(), 0);
  openni::OpenNI::shutdown();
}

TEST(SysrootCheck, SystemdNotifiesNobodyOutsideAService) {
  // Without NOTIFY_SOCKET sd_notify sends nothing and says so with 0.
  unsetenv("NOTIFY_SOCKET");
  EXPECT_EQ(sd_notify(0, "READY=1"), 0);
}

TEST(SysrootCheck, BenchmarkRuns) {
  class SilentReporter : public benchmark::BenchmarkReporter {
   public:
    bool ReportContext(const Context&) override { return true; }
    void ReportRuns(const std::vector<Run>&) override {}
  };
  int iterations = 0;
  benchmark::RegisterBenchmark("sysroot_check_count", [&iterations](benchmark::State& state) {
    for (auto _ : state) {
      ++iterations;
    }
  })->Iterations(3);
  SilentReporter reporter;
  EXPECT_EQ(benchmark::RunSpecifiedBenchmarks(&reporter), 1u);
  EXPECT_EQ(iterations, 3);
}
