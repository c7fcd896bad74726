// Frame-to-frame RGB-D odometry on TUM fr1_rpy_head (180 frames), all methods in one run on the
// same frames held in memory: OpenCV contrib's RgbdOdometry (dense photometric) and
// RgbdICPOdometry (photometric + point-to-plane ICP) against rankslam's photometric pipeline
// (ORB + MSSE) and its baseline (ORB + 2 cm RANSAC). The photometric pipeline runs twice: with
// rankslam's fixed-memory ORB extractor (the product) and with OpenCV's cv::ORB in its place.
//
// Each benchmark iteration runs the whole sequence; counters: ate_m (TUM ATE RMSE), ms_per_frame
// (median wall time of one frame), cpu_ms_per_frame (median thread CPU time), failed frames. A
// table with the ratios to rankslam photometric follows on stdout. Decoding the PNGs is not
// timed; converting to what each method takes is (rankslam: BGR to grey inside its loop; OpenCV:
// grey image and float depth in metres, converted per frame here). OpenCV's methods see the
// pinhole intrinsics without the lens distortion (they have no distortion model).
// BM_RankslamTeam runs photometric, geometric and fused tracking on 1 and 2 threads (slam.threads)
// side by side; cpu_ms_per_frame is the tracking thread's share then.
//   perf_odometry [benchmark flags] [--seed=N]   (N: SlamConfig::seed of the rankslam rows, default 1)

#include "rankslam/eval/metrics.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <benchmark/benchmark.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <exception>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace rankslam;

struct Frame {
  double stamp_s = 0.0;
  cv::Mat bgr;
  cv::Mat depth;  // CV_16UC1 raw
};

struct Sequence {
  std::string error;
  hal::Calibration calibration;
  eval::Trajectory ground_truth;
  std::vector<Frame> frames;
};

const Sequence& sequence() {
  static const Sequence loaded = [] {
    Sequence s;
    const fs::path dir = fs::path(RANKSLAM_SHARED_DATA) / "tum" / "fr1_rpy_head";
    if (!fs::is_directory(dir)) {
      s.error = "no shared data at " + dir.string();
      return s;
    }
    replay::Recording recording;
    if (auto error = replay::open_recording(dir, recording); !error.empty()) {
      s.error = error;
      return s;
    }
    auto ground_truth = eval::read_tum_trajectory(*recording.ground_truth);
    if (!ground_truth) {
      s.error = ground_truth.error();
      return s;
    }
    s.ground_truth = std::move(ground_truth).value();
    s.calibration = recording.calibration;
    replay::ReplayOptions options;
    options.load_ir = false;
    replay::ReplayDepthCamera camera(recording, options);
    if (auto error = camera.open(); !error.empty()) {
      s.error = error;
      return s;
    }
    hal::RgbdFrame frame;
    while (camera.read(frame, std::chrono::milliseconds(5000)) == hal::ReadStatus::kOk) {
      s.frames.push_back({frame.stamp_s, frame.rgb.clone(), frame.depth.clone()});
    }
    return s;
  }();
  return loaded;
}

double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

struct Outcome {
  double ate_m = 0.0;
  double ms_per_frame = 0.0;
  double cpu_ms_per_frame = 0.0;
  int failed = 0;
};

int& rankslam_seed() {
  static int seed = slam::SlamConfig{}.seed;
  return seed;
}

std::map<std::string, Outcome>& outcomes() {
  static std::map<std::string, Outcome> all;
  return all;
}

/// Runs `step(i, T_world_cam, failed)` over the sequence, timing each call.
template <class Step>
Outcome run_sequence(const Sequence& s, Step&& step) {
  eval::Trajectory estimate;
  estimate.reserve(s.frames.size());
  std::vector<double> wall_ms;
  std::vector<double> cpu_ms;
  Outcome outcome;
  for (std::size_t i = 0; i < s.frames.size(); ++i) {
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    bool failed = false;
    const auto start = std::chrono::steady_clock::now();
    const double cpu_start = thread_cpu_ms();
    step(i, T_world_cam, failed);
    cpu_ms.push_back(thread_cpu_ms() - cpu_start);
    wall_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    estimate.push_back({s.frames[i].stamp_s, T_world_cam});
    if (failed) ++outcome.failed;
  }
  auto ate = eval::compute_ate(s.ground_truth, estimate);
  outcome.ate_m = ate ? ate.value().translation_m.rmse : -1.0;
  outcome.ms_per_frame = median(wall_ms);
  outcome.cpu_ms_per_frame = median(cpu_ms);
  return outcome;
}

void report(benchmark::State& state, const std::string& name, const Outcome& outcome) {
  state.counters["ate_m"] = outcome.ate_m;
  state.counters["ms_per_frame"] = outcome.ms_per_frame;
  state.counters["cpu_ms_per_frame"] = outcome.cpu_ms_per_frame;
  state.counters["failed_frames"] = outcome.failed;
  outcomes()[name] = outcome;
}

void rankslam_odometry(benchmark::State& state, slam::Mode mode,
                       slam::OrbImplementation orb = slam::OrbImplementation::kFixedMemory,
                       int threads = slam::SlamConfig{}.threads, bool name_threads = false) {
  const Sequence& s = sequence();
  if (!s.error.empty()) {
    state.SkipWithError(s.error.c_str());
    return;
  }
  Outcome outcome;
  for (auto _ : state) {
    slam::SlamConfig config;
    config.mode = mode;
    config.seed = rankslam_seed();
    config.orb_implementation = orb;
    config.threads = threads;
    slam::SlamLoop loop(config, s.calibration);
    hal::RgbdFrame frame;
    outcome = run_sequence(s, [&](std::size_t i, Eigen::Isometry3d& T_world_cam, bool& failed) {
      frame.stamp_s = s.frames[i].stamp_s;
      frame.rgb = s.frames[i].bgr;
      frame.depth = s.frames[i].depth;
      const slam::FrameResult result = loop.process(frame);
      T_world_cam = result.T_world_cam;
      failed = result.status == slam::FrameStatus::kFailed;
    });
  }
  report(state,
         std::string("rankslam ") + std::string(slam::to_string(mode)) +
             (orb == slam::OrbImplementation::kOpenCv ? " cv::ORB" : "") +
             (name_threads ? ", " + std::to_string(threads) + (threads == 1 ? " thread" : " threads") : ""),
         outcome);
}

template <class OdometryType>
void opencv_odometry(benchmark::State& state, const char* name) {
  const Sequence& s = sequence();
  if (!s.error.empty()) {
    state.SkipWithError(s.error.c_str());
    return;
  }
  const auto& c = s.calibration.rgb;
  const cv::Mat K = (cv::Mat_<float>(3, 3) << static_cast<float>(c.fx), 0.0F, static_cast<float>(c.cx), 0.0F,
                     static_cast<float>(c.fy), static_cast<float>(c.cy), 0.0F, 0.0F, 1.0F);
  Outcome outcome;
  for (auto _ : state) {
    cv::Ptr<OdometryType> odometry = OdometryType::create(K);
    cv::Ptr<cv::rgbd::OdometryFrame> previous;
    Eigen::Isometry3d T_world_previous = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d last_motion = Eigen::Isometry3d::Identity();
    outcome = run_sequence(s, [&](std::size_t i, Eigen::Isometry3d& T_world_cam, bool& failed) {
      cv::Mat gray;
      cv::Mat depth_m;
      cv::cvtColor(s.frames[i].bgr, gray, cv::COLOR_BGR2GRAY);
      s.frames[i].depth.convertTo(depth_m, CV_32FC1, 1.0 / s.calibration.depth_scale);
      depth_m.setTo(std::numeric_limits<float>::quiet_NaN(), depth_m == 0.0F);
      cv::Ptr<cv::rgbd::OdometryFrame> current = cv::rgbd::OdometryFrame::create(gray, depth_m);
      odometry->prepareFrameCache(current, cv::rgbd::OdometryFrame::CACHE_ALL);
      if (previous) {
        // src = current, dst = previous: Rt maps current-frame points into the previous frame.
        cv::Mat Rt;
        if (odometry->compute(current, previous, Rt)) {
          Eigen::Matrix4d M;
          for (int r = 0; r < 4; ++r) {
            for (int col = 0; col < 4; ++col) M(r, col) = Rt.at<double>(r, col);
          }
          last_motion.matrix() = M;
        } else {
          failed = true;  // same policy as rankslam: constant velocity through the failure
        }
      }
      T_world_cam = T_world_previous * (previous ? last_motion : Eigen::Isometry3d::Identity());
      T_world_previous = T_world_cam;
      previous = current;
    });
  }
  report(state, name, outcome);
}

void BM_OpenCvRgbdOdometry(benchmark::State& state) {
  opencv_odometry<cv::rgbd::RgbdOdometry>(state, "OpenCV RgbdOdometry");
}
void BM_OpenCvRgbdIcpOdometry(benchmark::State& state) {
  opencv_odometry<cv::rgbd::RgbdICPOdometry>(state, "OpenCV RgbdICPOdometry");
}
void BM_RankslamPhotometric(benchmark::State& state) { rankslam_odometry(state, slam::Mode::kPhotometric); }
// The thread team side by side: one thread against the default team, in every mode.
void BM_RankslamTeam(benchmark::State& state) {
  rankslam_odometry(state, static_cast<slam::Mode>(state.range(0)), slam::OrbImplementation::kFixedMemory,
                    static_cast<int>(state.range(1)), true);
}
void BM_RankslamBaseline(benchmark::State& state) { rankslam_odometry(state, slam::Mode::kBaseline); }
void BM_RankslamPhotometricOpenCvOrb(benchmark::State& state) {
  rankslam_odometry(state, slam::Mode::kPhotometric, slam::OrbImplementation::kOpenCv);
}

BENCHMARK(BM_OpenCvRgbdOdometry)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_OpenCvRgbdIcpOdometry)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RankslamPhotometric)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RankslamBaseline)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RankslamPhotometricOpenCvOrb)->Iterations(1)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_RankslamTeam)
    ->ArgsProduct({{static_cast<int>(slam::Mode::kPhotometric), static_cast<int>(slam::Mode::kGeometric),
                    static_cast<int>(slam::Mode::kFused)},
                   {1, 2}})
    ->ArgNames({"mode", "threads"})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

void print_table() {
  const auto& all = outcomes();
  const auto reference = all.find("rankslam photometric");
  if (all.empty() || reference == all.end()) return;
  std::printf("\nfr1_rpy_head, %zu frames, frame to frame, rankslam seed %d (ratios: method / rankslam photometric)\n",
              sequence().frames.size(), rankslam_seed());
  std::printf("%-30s %9s %12s %14s %7s %11s %10s\n", "method", "ATE [m]", "ms/frame", "CPU ms/frame", "failed",
              "ATE ratio", "time ratio");
  for (const auto& [name, outcome] : all) {
    std::printf("%-30s %9.4f %12.2f %14.2f %7d %11.2f %10.2f\n", name.c_str(), outcome.ate_m, outcome.ms_per_frame,
                outcome.cpu_ms_per_frame, outcome.failed, outcome.ate_m / reference->second.ate_m,
                outcome.ms_per_frame / reference->second.ms_per_frame);
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  // The one flag of its own: what is left after Google Benchmark took its flags.
  if (argc == 2 && std::string(argv[1]).rfind("--seed=", 0) == 0) {
    try {
      rankslam_seed() = std::stoi(std::string(argv[1]).substr(7));
    } catch (const std::exception&) {
      std::fprintf(stderr, "perf_odometry: --seed wants an integer, got %s\n", argv[1]);
      return 1;
    }
    argc = 1;
  }
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  if (!sequence().error.empty()) {
    std::printf("perf_odometry: skipped: %s\n", sequence().error.c_str());
    return 0;
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  print_table();
  return 0;
}
