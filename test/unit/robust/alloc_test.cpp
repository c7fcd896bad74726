// Fixed memory in the per-frame loop: after one warm-up call, MSSE and RANSAC over every model
// allocate nothing. Counts global operator new/delete (replaced by the allocation-counter test library) and, outside sanitizer
// builds, malloc itself, because Eigen's heap temporaries bypass operator new.

#include <vector>

#include <gtest/gtest.h>

#include "allocation_counter.hpp"

#include "rankslam/robust/bearing.hpp"
#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/orientation.hpp"
#include "rankslam/robust/ransac.hpp"
#include "rankslam/robust/rigid.hpp"
#include "rankslam/robust/scalar.hpp"
#include "synthetic_correspondences.hpp"

namespace rankslam::robust {
namespace {

using test_support::CountAllocations;

TEST(Allocations, CounterSeesAllocations) {
  // The counters must be live, or a zero below would prove nothing.
  long new_calls = 0;
  long malloc_calls = 0;
  {
    CountAllocations count;
    auto* v = new std::vector<double>(100, 1.0);
    const Eigen::VectorXd x = Eigen::VectorXd::Ones(1000);  // Eigen allocates with malloc
    volatile double sink = x.sum() + (*v)[3];  // keeps both allocations observable
    (void)sink;
    delete v;
    new_calls = count.new_calls();
    malloc_calls = count.malloc_calls();
  }
  EXPECT_GE(new_calls, 2);
  if (test_support::counts_malloc()) {
    EXPECT_GE(malloc_calls, 3);
  }
}

TEST(Allocations, NoneAfterWarmUp) {
  constexpr int kMax = 800;
  testing::SceneConfig scene_config;
  scene_config.points = kMax;
  scene_config.outlier_fraction = 0.6;
  const testing::Scene big = testing::make_scene(scene_config);
  scene_config.points = 300;
  scene_config.seed = 2;
  const testing::Scene small = testing::make_scene(scene_config);

  RigidModel rigid(kMax);
  OrientationModel orientation(kMax);
  BearingModel bearing(kMax);
  ScalarModel scalar;
  RobustWorkspace workspace(kMax);
  std::vector<double> sigmas(kMax);
  std::vector<double> values(kMax);
  for (int i = 0; i < kMax; ++i) values[static_cast<std::size_t>(i)] = 0.01 * (i % 97);
  Eigen::Matrix3Xd normals = big.src.colwise().normalized();
  const std::vector<double> weights(kMax, 0.5);
  MsseConfig msse_config;
  RansacConfig ransac_config;
  RigidMotionGate gate;
  gate.T_t_s_predicted = big.T_t_s;

  const auto frame = [&](const testing::Scene& scene, int round) {
    const auto n = static_cast<std::size_t>(scene.src.cols());
    const std::span<const double> w(weights.data(), n);
    const std::span<double> s(sigmas.data(), n);
    EXPECT_EQ(rigid.set_correspondences(scene.src, scene.dst, w), RobustStatus::kOk);
    EXPECT_EQ(correspondence_sigmas_m(scene.src, scene.dst, DepthNoiseModel{}, s),
              RobustStatus::kOk);
    msse_config.seed = static_cast<std::uint64_t>(round);
    EXPECT_TRUE(estimate_msse(rigid, msse_config, workspace).ok());
    EXPECT_TRUE(estimate_msse(rigid, msse_config, workspace, s).ok());
    EXPECT_TRUE(estimate_msse(rigid, msse_config, workspace, {}, gate).ok() || true);
    EXPECT_TRUE(estimate_ransac(rigid, ransac_config, workspace).ok());
    Eigen::Isometry3d T;
    EXPECT_EQ(fit_rigid(scene.src, scene.dst, w, T), RigidFitStatus::kOk);
    EXPECT_EQ(orientation.set_normals(normals.leftCols(static_cast<Eigen::Index>(n))),
              RobustStatus::kOk);
    EXPECT_TRUE(estimate_msse(orientation, msse_config, workspace).ok());
    // The destination points' directions are bearings of the source points seen from T_t_s.
    EXPECT_EQ(bearing.set_correspondences(scene.src, scene.dst), RobustStatus::kOk);
    EXPECT_EQ(estimate_msse(bearing, msse_config, workspace).status, RobustStatus::kOk);
    EXPECT_EQ(scalar.set_values(std::span<const double>(values.data(), n)), RobustStatus::kOk);
    EXPECT_TRUE(estimate_msse(scalar, msse_config, workspace).ok());
    // Failures must not allocate either.
    const Eigen::Matrix3Xd::ConstColsBlockXpr two = scene.src.leftCols(2);
    EXPECT_EQ(rigid.set_correspondences(two, two), RobustStatus::kOk);
    EXPECT_EQ(estimate_msse(rigid, msse_config, workspace).status, RobustStatus::kTooFewPoints);
  };

  frame(big, 0);  // warm-up: first use of lazily initialised library state
  CountAllocations count;
  for (int round = 1; round <= 20; ++round) frame(round % 2 == 0 ? big : small, round);
  const long new_calls = count.new_calls();
  const long malloc_calls = count.malloc_calls();
  EXPECT_EQ(new_calls, 0);
  EXPECT_EQ(malloc_calls, 0);
}

}  // namespace
}  // namespace rankslam::robust
