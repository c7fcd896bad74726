// MSSE against fixed-threshold RANSAC on synthetic Kinect-like correspondences.
//
// First prints a table: mean / 95th-percentile translation error [mm], mean rotation error [deg],
// mean time per call and the number of scenes beyond 2 mm / 0.2 deg, against the uniform-outlier
// ratio, over 50 scenes, for MSSE (κ = 0.1) as the thesis runs it (one refit) and with
// refinement rounds, both plain and with per-point Kinect noise normalisation, RANSAC at 5, 10
// and 20 mm, and the weighted least-squares fit on the true inliers as the floor.
// Then runs the Google Benchmark timings (n = 500, H = 1000 unless stated).
//   perf_robust [--table_seeds=N] [--no_table] [benchmark flags]

#include <algorithm>
#include <ctime>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/orientation.hpp"
#include "rankslam/robust/ransac.hpp"
#include "rankslam/robust/rigid.hpp"
#include "rankslam/robust/scalar.hpp"
#include "synthetic_correspondences.hpp"

namespace {

namespace robust = rankslam::robust;
namespace testing = rankslam::robust::testing;

constexpr int kPoints = 500;

enum class Kind : std::uint8_t { kMsse, kRansac, kOracle };

struct Method {
  const char* name;
  Kind kind;
  bool normalised;           // MSSE: rank r_i / sigma_i; oracle: weight 1 / sigma_i^2
  int refine_iterations;     // MSSE
  double ransac_threshold_m; // RANSAC
};

struct Sample {
  double translation_mm;
  double rotation_deg;
  double time_us;
};

/// Thread CPU time: the table stays meaningful while other jobs share the machine.
double thread_cpu_us() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e6 + static_cast<double>(ts.tv_nsec) * 1e-3;
}

Sample run_method(const Method& method, const testing::Scene& scene, robust::RigidModel& model,
                  robust::RobustWorkspace& workspace, std::vector<double>& sigmas,
                  std::vector<double>& inverse_variances, std::vector<int>& true_inliers) {
  (void)model.set_correspondences(scene.src, scene.dst);
  (void)robust::correspondence_sigmas_m(scene.src, scene.dst, robust::DepthNoiseModel{}, sigmas);
  Eigen::Isometry3d estimate = Eigen::Isometry3d::Identity();
  const double start_us = thread_cpu_us();
  switch (method.kind) {
    case Kind::kMsse: {
      robust::MsseConfig config;
      config.refine_iterations = method.refine_iterations;
      const auto result = robust::estimate_msse(
          model, config, workspace,
          method.normalised ? std::span<const double>(sigmas) : std::span<const double>());
      estimate = result.model;
      break;
    }
    case Kind::kRansac: {
      robust::RansacConfig config;
      config.inlier_threshold = method.ransac_threshold_m;
      const auto result = robust::estimate_ransac(model, config, workspace);
      estimate = result.model;
      break;
    }
    case Kind::kOracle: {
      true_inliers.clear();
      for (std::size_t i = 0; i < scene.kind.size(); ++i) {
        if (scene.kind[i] == testing::PointKind::kInlier) {
          true_inliers.push_back(static_cast<int>(i));
        }
        inverse_variances[i] = 1.0 / (sigmas[i] * sigmas[i]);
      }
      (void)model.fit_inliers(true_inliers, method.normalised ? inverse_variances.data() : nullptr,
                              estimate);
      break;
    }
  }
  const double time_us = thread_cpu_us() - start_us;
  const testing::PoseError e = testing::pose_error(estimate, scene.T_t_s);
  return {e.translation_m * 1e3, e.rotation_rad * 180.0 / 3.14159265358979323846, time_us};
}

void print_table(int seeds) {
  const Method methods[] = {
      {"MSSE (thesis: 1 refit)", Kind::kMsse, false, 0, 0.0},
      {"MSSE (3 refine rounds)", Kind::kMsse, false, 3, 0.0},
      {"MSSE + r/sigma, 1 refit", Kind::kMsse, true, 0, 0.0},
      {"MSSE + r/sigma", Kind::kMsse, true, 3, 0.0},
      {"RANSAC 5 mm", Kind::kRansac, false, 0, 0.005},
      {"RANSAC 10 mm", Kind::kRansac, false, 0, 0.010},
      {"RANSAC 20 mm", Kind::kRansac, false, 0, 0.020},
      {"oracle LS, 1/sigma^2", Kind::kOracle, true, 0, 0.0},
  };
  const double ratios[] = {0.0, 0.2, 0.4, 0.6, 0.7, 0.8, 0.85};
  robust::RigidModel model(kPoints);
  robust::RobustWorkspace workspace(kPoints);
  std::vector<double> sigmas(kPoints);
  std::vector<double> inverse_variances(kPoints);
  std::vector<int> true_inliers;
  true_inliers.reserve(kPoints);

  std::printf("\nRigid registration, n = %d correspondences, H = 1000, kappa = 0.1, %d scenes "
              "(seeds) per row.\n", kPoints, seeds);
  std::printf("Points 0.5-4 m, noise sigma_z = 1.425e-3 z^2 along the ray + 1 mm lateral on both "
              "ends; uniform outliers in the view frustum.\n");
  std::printf("Cell: mean/p95 translation error [mm], mean rotation error [deg], "
              "mean CPU time [ms], "
              "number of scenes beyond 2 mm or 0.2 deg.\n");
  std::printf("Time is thread CPU time per call (MSSE/RANSAC only; the oracle is one weighted "
              "fit).\n");
  std::printf("Oracle: least squares on the true inliers weighted by 1/sigma^2 (the floor).\n\n");
  std::printf("%-5s", "out%");
  for (const Method& m : methods) std::printf(" | %-25s", m.name);
  std::printf("\n");
  for (const double ratio : ratios) {
    std::printf("%-5.0f", ratio * 100.0);
    for (const Method& m : methods) {
      std::vector<double> t_mm;
      double r_sum = 0.0;
      double time_sum = 0.0;
      int beyond = 0;
      for (int s = 0; s < seeds; ++s) {
        testing::SceneConfig config;
        config.points = kPoints;
        config.outlier_fraction = ratio;
        config.seed = 1000 + static_cast<std::uint64_t>(s);
        const testing::Scene scene = testing::make_scene(config);
        const Sample sample =
            run_method(m, scene, model, workspace, sigmas, inverse_variances, true_inliers);
        t_mm.push_back(sample.translation_mm);
        r_sum += sample.rotation_deg;
        time_sum += sample.time_us;
        beyond += sample.translation_mm > 2.0 || sample.rotation_deg > 0.2 ? 1 : 0;
      }
      std::sort(t_mm.begin(), t_mm.end());
      double t_mean = 0.0;
      for (const double t : t_mm) t_mean += t;
      t_mean /= static_cast<double>(seeds);
      const double t_p95 = t_mm[static_cast<std::size_t>(0.95 * (seeds - 1))];
      char cell[64];
      std::snprintf(cell, sizeof cell, "%5.2f/%6.2f %5.3f %4.2f %2d", t_mean, t_p95,
                    r_sum / seeds, time_sum / seeds * 1e-3, beyond);
      std::printf(" | %-25s", cell);
    }
    std::printf("\n");
    std::fflush(stdout);
  }
  std::printf("\n");
}

testing::Scene scene_for(double outlier_fraction, int points = kPoints) {
  testing::SceneConfig config;
  config.points = points;
  config.outlier_fraction = outlier_fraction;
  config.seed = 7;
  return testing::make_scene(config);
}

void BM_Msse(benchmark::State& state) {
  const auto n = static_cast<int>(state.range(0));
  const testing::Scene scene = scene_for(static_cast<double>(state.range(1)) / 100.0, n);
  robust::RigidModel model(n);
  robust::RobustWorkspace workspace(n);
  const robust::MsseConfig config;
  int inliers = 0;
  for (auto _ : state) {
    (void)model.set_correspondences(scene.src, scene.dst);
    const auto result = robust::estimate_msse(model, config, workspace);
    inliers = result.inlier_count;
    benchmark::DoNotOptimize(result.model);
  }
  state.counters["inliers"] = inliers;
}
BENCHMARK(BM_Msse)
    ->ArgsProduct({{300, 500, 800}, {0, 50, 80}})
    ->Unit(benchmark::kMillisecond);

void BM_MsseNormalised(benchmark::State& state) {
  const testing::Scene scene = scene_for(static_cast<double>(state.range(0)) / 100.0);
  robust::RigidModel model(kPoints);
  robust::RobustWorkspace workspace(kPoints);
  std::vector<double> sigmas(kPoints);
  for (auto _ : state) {
    (void)model.set_correspondences(scene.src, scene.dst);
    (void)robust::correspondence_sigmas_m(scene.src, scene.dst, {}, sigmas);
    const auto result = robust::estimate_msse(model, {}, workspace, sigmas);
    benchmark::DoNotOptimize(result.model);
  }
}
BENCHMARK(BM_MsseNormalised)->Arg(0)->Arg(50)->Arg(80)->Unit(benchmark::kMillisecond);

void BM_Ransac(benchmark::State& state) {
  const testing::Scene scene = scene_for(static_cast<double>(state.range(0)) / 100.0);
  robust::RigidModel model(kPoints);
  robust::RobustWorkspace workspace(kPoints);
  robust::RansacConfig config;
  config.inlier_threshold = 0.01;
  for (auto _ : state) {
    (void)model.set_correspondences(scene.src, scene.dst);
    const auto result = robust::estimate_ransac(model, config, workspace);
    benchmark::DoNotOptimize(result.model);
  }
}
BENCHMARK(BM_Ransac)->Arg(0)->Arg(50)->Arg(80)->Unit(benchmark::kMillisecond);

void BM_RigidMinimalFit(benchmark::State& state) {
  const testing::Scene scene = scene_for(0.0);
  robust::RigidModel model(kPoints);
  (void)model.set_correspondences(scene.src, scene.dst);
  const int sample[3] = {0, 1, 2};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (auto _ : state) {
    benchmark::DoNotOptimize(model.fit_sample(sample, T));
    benchmark::DoNotOptimize(T);
  }
}
BENCHMARK(BM_RigidMinimalFit);

void BM_RigidResiduals(benchmark::State& state) {
  const testing::Scene scene = scene_for(0.0);
  robust::RigidModel model(kPoints);
  (void)model.set_correspondences(scene.src, scene.dst);
  std::vector<double> out(kPoints);
  for (auto _ : state) {
    model.squared_residuals(scene.T_t_s, 0, kPoints, out.data());
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_RigidResiduals);

void BM_RigidSelectionScores(benchmark::State& state) {
  const testing::Scene scene = scene_for(0.0);
  robust::RigidModel model(kPoints);
  (void)model.set_correspondences(scene.src, scene.dst);
  std::vector<double> out(kPoints);
  for (auto _ : state) {
    model.selection_scores(scene.T_t_s, 0, kPoints, out.data());
    benchmark::DoNotOptimize(out.data());
  }
}
BENCHMARK(BM_RigidSelectionScores);

void BM_ScalarSegmentation(benchmark::State& state) {
  const auto n = static_cast<int>(state.range(0));
  std::vector<double> values(static_cast<std::size_t>(n));
  robust::Pcg32 rng(3);
  for (double& v : values) v = rng.uniform01() < 0.8 ? rng.uniform01() : 5.0 + rng.uniform01();
  robust::ScalarModel model;
  (void)model.set_values(values);
  robust::RobustWorkspace workspace(n);
  robust::MsseConfig config;
  config.min_inlier_fraction = 0.2;
  for (auto _ : state) {
    const auto result = robust::estimate_msse(model, config, workspace);
    benchmark::DoNotOptimize(result.inlier_count);
  }
}
BENCHMARK(BM_ScalarSegmentation)->Arg(5000)->Arg(100000)->Unit(benchmark::kMicrosecond);

void BM_OrientationMsse(benchmark::State& state) {
  const int n = 5000;
  Eigen::Matrix3Xd normals(3, n);
  robust::Pcg32 rng(5);
  for (int i = 0; i < n; ++i) {
    const double u = rng.uniform01();
    const Eigen::Vector3d base = u < 0.5 ? Eigen::Vector3d(0, -1, 0) : Eigen::Vector3d(0, 0, -1);
    normals.col(i) =
        (base + 0.03 * Eigen::Vector3d(rng.uniform01() - 0.5, rng.uniform01() - 0.5,
                                       rng.uniform01() - 0.5))
            .normalized();
  }
  robust::OrientationModel model(n);
  (void)model.set_normals(normals);
  robust::RobustWorkspace workspace(n);
  robust::MsseConfig config;
  config.hypotheses = static_cast<int>(state.range(0));
  config.min_inlier_fraction = 0.2;
  for (auto _ : state) {
    const auto result = robust::estimate_msse(model, config, workspace);
    benchmark::DoNotOptimize(result.model);
  }
}
BENCHMARK(BM_OrientationMsse)->Arg(100)->Arg(500)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  int seeds = 50;
  bool table = true;
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    if (std::strncmp(argv[i], "--table_seeds=", 14) == 0) {
      seeds = std::max(1, std::atoi(argv[i] + 14));
    } else if (std::strcmp(argv[i], "--no_table") == 0) {
      table = false;
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (table) print_table(seeds);
  int rest_argc = static_cast<int>(rest.size());
  benchmark::Initialize(&rest_argc, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
