// ORB extraction alone on the grey images of TUM fr1_rpy_head (180 frames held in memory):
// rankslam's fixed-memory OrbExtractor against OpenCV's cv::ORB with the same parameters (the
// SLAM defaults: 1000 features, scale 1.2, 8 levels, FAST threshold 20, Harris ranking).
// Counters: ms_per_frame (median wall time of one image), cpu_ms_per_frame (median process CPU
// time of one image: OpenCV may spread its work over threads), keypoints (mean per image).
//   perf_orb_extractor [benchmark flags]

#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/orb_extractor.hpp"

#include <benchmark/benchmark.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace rankslam;

struct Images {
  std::string error;
  std::vector<cv::Mat> gray;
};

const Images& images() {
  static const Images loaded = [] {
    Images s;
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
    replay::ReplayOptions options;
    options.load_ir = false;
    replay::ReplayDepthCamera camera(recording, options);
    if (auto error = camera.open(); !error.empty()) {
      s.error = error;
      return s;
    }
    hal::RgbdFrame frame;
    while (camera.read(frame, std::chrono::milliseconds(5000)) == hal::ReadStatus::kOk) {
      cv::Mat gray;
      cv::cvtColor(frame.rgb, gray, cv::COLOR_BGR2GRAY);
      s.gray.push_back(gray);
    }
    return s;
  }();
  return loaded;
}

double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2), values.end());
  return values[values.size() / 2];
}

/// Runs `extract(image) -> keypoint count` over every image, timing each call.
template <class Extract>
void run(benchmark::State& state, Extract&& extract) {
  const Images& s = images();
  if (!s.error.empty()) {
    state.SkipWithError(s.error.c_str());
    return;
  }
  std::vector<double> wall_ms;
  std::vector<double> cpu_ms;
  double keypoints = 0.0;
  for (auto _ : state) {
    wall_ms.clear();
    cpu_ms.clear();
    keypoints = 0.0;
    for (const cv::Mat& gray : s.gray) {
      const auto start = std::chrono::steady_clock::now();
      const double cpu_start = process_cpu_ms();
      keypoints += static_cast<double>(extract(gray));
      cpu_ms.push_back(process_cpu_ms() - cpu_start);
      wall_ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    }
  }
  state.counters["ms_per_frame"] = median(wall_ms);
  state.counters["cpu_ms_per_frame"] = median(cpu_ms);
  state.counters["keypoints"] = keypoints / static_cast<double>(s.gray.size());
}

void BM_OrbExtractor(benchmark::State& state) {
  const slam::SlamConfig config;
  slam::OrbExtractorSettings settings;
  settings.max_features = config.orb_features;
  settings.scale_factor = static_cast<float>(config.orb_scale_factor);
  settings.levels = config.orb_levels;
  settings.fast_threshold = config.orb_fast_threshold;
  slam::OrbExtractor extractor(settings);
  run(state, [&](const cv::Mat& gray) {
    (void)extractor.extract(gray);
    return extractor.keypoints().size();
  });
}

void BM_OpenCvOrb(benchmark::State& state) {
  const slam::SlamConfig config;
  cv::Ptr<cv::ORB> orb = cv::ORB::create(config.orb_features, static_cast<float>(config.orb_scale_factor),
                                         config.orb_levels, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31,
                                         config.orb_fast_threshold);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  run(state, [&](const cv::Mat& gray) {
    keypoints.clear();
    orb->detectAndCompute(gray, cv::noArray(), keypoints, descriptors);
    return keypoints.size();
  });
}

BENCHMARK(BM_OrbExtractor)->Iterations(3)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_OpenCvOrb)->Iterations(3)->Unit(benchmark::kMillisecond);

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  if (!images().error.empty()) {
    std::printf("perf_orb_extractor: skipped: %s\n", images().error.c_str());
    return 0;
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
