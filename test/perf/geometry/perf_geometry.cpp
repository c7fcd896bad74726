// perf_geometry: the geometric front-end's speed on fr1_rpy_head (Google Benchmark).
//
//  - BM_GeometricFrame: one frame of depth-only odometry as the SLAM loop runs it: extract
//    (cloud → keypoints → SHOT) and register_frames (matches → MSSE → ICP) against the previous
//    frame, cycling over the recording, on a thread team of 1 or 2 (the robot computer's cores).
//    Counters: the per-frame median and 90th percentile of the wall time, with and without the
//    ICP refinement (cloud → keypoints → SHOT → matches → MSSE: median_frontend_wall_ms, the
//    figure the front-end's speed target names), the CPU time of all threads together
//    (median_frontend_cpu_ms: what the team costs in total; on a machine shared with other work,
//    the wall time is an upper bound), and each stage's mean latency.
//  - Stage benchmarks for the breakdown, and mutual matching of ~400 × 400 SHOT descriptors by
//    the exhaustive kernels against nanoflann k-d trees in 352 dimensions.
//
// Skips with a message when the shared data (RANKSLAM_SHARED_DATA) is absent.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <memory>
#include <vector>

#include <nanoflann.hpp>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "geometry_bench_support.hpp"
#include "rankslam/geometry/frontend.hpp"
#include "rankslam/geometry/matching.hpp"
#include "rankslam/camera/depth_camera.hpp"

namespace {

using namespace rankslam;
using namespace rankslam::geometry;

struct Data {
  bench::DepthSequence sequence;
  std::unique_ptr<camera::DepthCameraModel> camera;
  std::string error;
};

const Data& data() {
  static const Data loaded = [] {
    Data d;
    const auto root = bench::shared_recording("fr1_rpy_head");
    if (root.empty()) {
      d.error = "shared data RANKSLAM_SHARED_DATA/tum/fr1_rpy_head is absent";
      return d;
    }
    d.error = bench::load_depth_sequence(root, d.sequence);
    if (d.error.empty()) {
      d.camera = std::make_unique<camera::DepthCameraModel>(d.sequence.calibration.rgb,
                                                          d.sequence.calibration.depth_scale);
    }
    return d;
  }();
  return loaded;
}

// CPU time of the whole process: every thread of the team.
double cpu_ms() {
  timespec now{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) * 1e3 + static_cast<double>(now.tv_nsec) * 1e-6;
}

double wall_ms() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<double>(now.tv_sec) * 1e3 + static_cast<double>(now.tv_nsec) * 1e-6;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

bool ready(benchmark::State& state) {
  if (!data().error.empty()) {
    state.SkipWithError(data().error.c_str());
    return false;
  }
  return true;
}

void BM_GeometricFrame(benchmark::State& state) {
  if (!ready(state)) return;
  const auto& frames = data().sequence.depth;
  GeometryConfig config;
  config.keypoint_method = static_cast<KeypointMethod>(state.range(0));
  parallel::ThreadTeam team;
  if (const std::string error = team.start(static_cast<int>(state.range(1))); !error.empty()) {
    state.SkipWithError(error.c_str());
    return;
  }
  GeometricFrontend frontend;
  if (const std::string error = frontend.configure(*data().camera, config, {}, &team); !error.empty()) {
    state.SkipWithError(error.c_str());
    return;
  }
  GeometricFeatures previous = frontend.make_features();
  GeometricFeatures current = frontend.make_features();
  (void)frontend.extract(frames[0], previous);
  std::size_t next = 1;
  std::vector<double> wall;
  std::vector<double> cpu;
  std::vector<double> frontend_wall;  // without the ICP stage
  std::vector<double> frontend_cpu;   // without the ICP stage (which runs on the caller only)
  StageTimes stages;
  int frames_timed = 0;
  int failed = 0;
  for (auto _ : state) {
    const double w0 = wall_ms();
    const double c0 = cpu_ms();
    (void)frontend.extract(frames[next], current);
    const StageTimes extract_times = frontend.last_times();
    const FrameRegistration r = frontend.register_frames(previous, current);
    const double c1 = cpu_ms();
    const double w1 = wall_ms();
    const StageTimes& t = frontend.last_times();
    stages.cloud_ms += extract_times.cloud_ms;
    stages.keypoints_ms += extract_times.keypoints_ms;
    stages.descriptors_ms += extract_times.descriptors_ms;
    stages.matching_ms += t.matching_ms;
    stages.msse_ms += t.msse_ms;
    stages.icp_ms += t.icp_ms;
    ++frames_timed;
    failed += r.ok ? 0 : 1;
    wall.push_back(w1 - w0);
    cpu.push_back(c1 - c0);
    frontend_wall.push_back(w1 - w0 - t.icp_ms);
    frontend_cpu.push_back(c1 - c0 - t.icp_ms);
    std::swap(previous, current);
    if (++next == frames.size()) {
      next = 1;
      (void)frontend.extract(frames[0], previous);
    }
  }
  state.counters["median_wall_ms"] = quantile(wall, 0.5);
  state.counters["p90_wall_ms"] = quantile(wall, 0.9);
  state.counters["median_cpu_ms"] = quantile(cpu, 0.5);
  state.counters["p90_cpu_ms"] = quantile(cpu, 0.9);
  state.counters["median_frontend_wall_ms"] = quantile(frontend_wall, 0.5);
  state.counters["p90_frontend_wall_ms"] = quantile(frontend_wall, 0.9);
  state.counters["median_frontend_cpu_ms"] = quantile(frontend_cpu, 0.5);
  state.counters["p90_frontend_cpu_ms"] = quantile(frontend_cpu, 0.9);
  const double n = std::max(frames_timed, 1);
  state.counters["cloud_ms"] = stages.cloud_ms / n;
  state.counters["keypoints_ms"] = stages.keypoints_ms / n;
  state.counters["shot_ms"] = stages.descriptors_ms / n;
  state.counters["match_ms"] = stages.matching_ms / n;
  state.counters["msse_ms"] = stages.msse_ms / n;
  state.counters["icp_ms"] = stages.icp_ms / n;
  state.counters["failed"] = failed;
}
BENCHMARK(BM_GeometricFrame)
    ->ArgsProduct({{static_cast<int>(KeypointMethod::kIs3d), static_cast<int>(KeypointMethod::kRos)}, {1, 2}})
    ->ArgNames({"method(0=is3d,1=ros)", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(358);  // every frame pair of the recording twice

void BM_CloudPreprocessing(benchmark::State& state) {
  if (!ready(state)) return;
  CloudPreprocessor preprocessor;
  (void)preprocessor.configure(*data().camera, GeometryConfig{}, 16384);
  SampledCloud cloud = preprocessor.make_cloud();
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(preprocessor.process(data().sequence.depth[i], cloud));
    i = (i + 1) % data().sequence.depth.size();
  }
  state.counters["sampled_points"] = cloud.size;
}
BENCHMARK(BM_CloudPreprocessing)->Unit(benchmark::kMillisecond);

// Descriptors of two consecutive frames, for the matching benchmarks.
struct DescriptorPair {
  std::vector<float> a;
  std::vector<float> b;
  int na = 0;
  int nb = 0;
};

const DescriptorPair& descriptor_pair() {
  static const DescriptorPair pair = [] {
    DescriptorPair p;
    if (!data().error.empty()) return p;
    GeometricFrontend frontend;
    (void)frontend.configure(*data().camera, GeometryConfig{});
    GeometricFeatures f = frontend.make_features();
    (void)frontend.extract(data().sequence.depth[20], f);
    p.na = f.count;
    p.a.assign(f.descriptors.begin(), f.descriptors.begin() + static_cast<std::ptrdiff_t>(f.count) * kShotSize);
    (void)frontend.extract(data().sequence.depth[21], f);
    p.nb = f.count;
    p.b.assign(f.descriptors.begin(), f.descriptors.begin() + static_cast<std::ptrdiff_t>(f.count) * kShotSize);
    return p;
  }();
  return pair;
}

void BM_MatchExhaustive(benchmark::State& state) {
  if (!ready(state)) return;
  const DescriptorPair& d = descriptor_pair();
  DescriptorMatcher matcher;
  constexpr DescriptorMatcher::Kernel kKernels[] = {DescriptorMatcher::Kernel::kBest, DescriptorMatcher::Kernel::kPortable,
                                                     DescriptorMatcher::Kernel::kFloat};
  (void)matcher.configure(1000, kShotSize, kKernels[state.range(0)]);
  std::vector<DescriptorMatch> out(1000);
  int matches = 0;
  for (auto _ : state) {
    matches = matcher.match(d.a.data(), d.na, d.b.data(), d.nb, out);
    benchmark::DoNotOptimize(matches);
  }
  state.counters["matches"] = matches;
  state.counters["vector"] = matcher.uses_vector_kernel() ? 1 : 0;
  state.counters["vnni"] = matcher.uses_vnni() ? 1 : 0;
  state.SetLabel(std::to_string(d.na) + "x" + std::to_string(d.nb));
}
// kernel 0: the best (8-bit pass where the CPU has AVX-512 VNNI), 1: portable, 2: float only.
BENCHMARK(BM_MatchExhaustive)->Arg(0)->Arg(1)->Arg(2)->ArgName("kernel")->Unit(benchmark::kMicrosecond);

// ORB-sized binary descriptors (1000 × 1000 of 32 bytes): rankslam's two-way nearest scan with
// its vector kernel and with its portable loop, against OpenCV's brute-force Hamming matcher
// with cross-check (the same mutual matches) in the same run.
struct BinaryPair {
  cv::Mat a, b;
};

const BinaryPair& binary_pair() {
  static const BinaryPair pair = [] {
    BinaryPair p{cv::Mat(1000, 32, CV_8UC1), cv::Mat(1000, 32, CV_8UC1)};
    cv::RNG rng(42);
    rng.fill(p.a, cv::RNG::UNIFORM, 0, 256);
    rng.fill(p.b, cv::RNG::UNIFORM, 0, 256);
    return p;
  }();
  return pair;
}

void BM_HammingNearest(benchmark::State& state) {
  const BinaryPair& d = binary_pair();
  HammingNearest nearest;
  nearest.reserve(1000, state.range(0) == 0);
  for (auto _ : state) {
    nearest.scan(d.a, d.b);
    benchmark::DoNotOptimize(nearest.nearest_target(0));
  }
  state.counters["vector"] = nearest.uses_vector_kernel() ? 1 : 0;
}
// kernel 0: the vector kernel where the CPU has one, 1: portable.
BENCHMARK(BM_HammingNearest)->Arg(0)->Arg(1)->ArgName("kernel")->Unit(benchmark::kMicrosecond);

void BM_HammingOpenCvCrossCheck(benchmark::State& state) {
  const BinaryPair& d = binary_pair();
  cv::BFMatcher matcher(cv::NORM_HAMMING, true);
  std::vector<cv::DMatch> matches;
  for (auto _ : state) {
    matcher.match(d.a, d.b, matches);
    benchmark::DoNotOptimize(matches.data());
  }
  state.counters["matches"] = static_cast<double>(matches.size());
}
BENCHMARK(BM_HammingOpenCvCrossCheck)->Unit(benchmark::kMicrosecond);

struct DescriptorSet {
  const float* data = nullptr;
  int count = 0;
  [[nodiscard]] std::size_t kdtree_get_point_count() const { return static_cast<std::size_t>(count); }
  [[nodiscard]] float kdtree_get_pt(std::size_t i, std::size_t dim) const { return data[i * kShotSize + dim]; }
  template <class B>
  bool kdtree_get_bbox(B& /*bb*/) const { return false; }
};
using DescriptorTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, DescriptorSet>, DescriptorSet, kShotSize>;

void BM_MatchKdTree(benchmark::State& state) {
  if (!ready(state)) return;
  const DescriptorPair& d = descriptor_pair();
  int matches = 0;
  for (auto _ : state) {
    // Both directions: a tree per side, nearest neighbour of every descriptor in the other.
    const DescriptorSet set_a{d.a.data(), d.na};
    const DescriptorSet set_b{d.b.data(), d.nb};
    DescriptorTree tree_a(kShotSize, set_a, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    DescriptorTree tree_b(kShotSize, set_b, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    tree_a.buildIndex();
    tree_b.buildIndex();
    std::vector<std::uint32_t> a_to_b(static_cast<std::size_t>(d.na));
    std::vector<std::uint32_t> b_to_a(static_cast<std::size_t>(d.nb));
    float distance = 0.0F;
    for (int i = 0; i < d.na; ++i) tree_b.knnSearch(d.a.data() + static_cast<std::ptrdiff_t>(i) * kShotSize, 1, &a_to_b[static_cast<std::size_t>(i)], &distance);
    for (int j = 0; j < d.nb; ++j) tree_a.knnSearch(d.b.data() + static_cast<std::ptrdiff_t>(j) * kShotSize, 1, &b_to_a[static_cast<std::size_t>(j)], &distance);
    matches = 0;
    for (int i = 0; i < d.na; ++i) matches += b_to_a[a_to_b[static_cast<std::size_t>(i)]] == static_cast<std::uint32_t>(i) ? 1 : 0;
    benchmark::DoNotOptimize(matches);
  }
  state.counters["matches"] = matches;
  state.SetLabel(std::to_string(d.na) + "x" + std::to_string(d.nb));
}
BENCHMARK(BM_MatchKdTree)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
