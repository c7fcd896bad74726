// ROS2D's extraction time against OpenCV SIFT's at 752×480 on a real EuRoC V1_01 cam0 frame:
// detection alone and detection + descriptors, ROS2D with all its features and capped to
// SIFT's count (max_features) so both describe as many. OpenCV runs on one thread
// (cv::setNumThreads(1)), as ROS2D does. Counter: keypoints per image.
//   perf_features --benchmark_repetitions=3 [benchmark flags]

#include "rankslam/features/extractor.hpp"

#include <benchmark/benchmark.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using rankslam::features::ExtractorOptions;
using rankslam::features::FeatureExtractor;
using rankslam::features::FeatureKind;

const cv::Mat& frame() {
  static const cv::Mat image = [] {
    fs::path data = RANKSLAM_SHARED_DATA;
    if (const char* env = std::getenv("RANKSLAM_SHARED_DATA"); env && *env) data = env;
    const fs::path dir = data / "euroc" / "V1_01_easy_head" / "mav0" / "cam0" / "data";
    std::vector<std::string> names;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(dir, ec))
      if (e.path().extension() == ".png") names.push_back(e.path().string());
    std::sort(names.begin(), names.end());
    return names.empty() ? cv::Mat() : cv::imread(names.front(), cv::IMREAD_GRAYSCALE);
  }();
  return image;
}

/// SIFT's keypoint count on the frame: the cap of the equal-count ROS2D runs.
int sift_count() {
  static const int count = [] {
    std::vector<cv::KeyPoint> k;
    cv::SIFT::create()->detect(frame(), k);
    return static_cast<int>(k.size());
  }();
  return count;
}

template <class Run>
void time_it(benchmark::State& state, Run&& run) {
  if (frame().empty()) {
    state.SkipWithError("no EuRoC V1_01_easy_head cam0 frame under the shared data");
    return;
  }
  std::size_t n = 0;
  for (auto _ : state) {
    n = run();
    benchmark::ClobberMemory();
  }
  state.counters["keypoints"] = static_cast<double>(n);
}

void ros2d(benchmark::State& state, bool describe, bool capped) {
  ExtractorOptions options;
  options.kind = FeatureKind::ros2d;
  options.max_features = capped ? sift_count() : 0;
  FeatureExtractor extractor(options);
  std::vector<cv::KeyPoint> k;
  cv::Mat d;
  if (!frame().empty()) extractor.reserve(frame().size());
  time_it(state, [&] {
    if (describe) {
      extractor.extract(frame(), k, d);
    } else {
      extractor.detect(frame(), k);
    }
    return k.size();
  });
}

void sift(benchmark::State& state, bool describe) {
  cv::Ptr<cv::SIFT> detector = cv::SIFT::create();
  std::vector<cv::KeyPoint> k;
  cv::Mat d;
  time_it(state, [&] {
    if (describe) {
      detector->detectAndCompute(frame(), cv::noArray(), k, d);
    } else {
      detector->detect(frame(), k);
    }
    return k.size();
  });
}

void BM_Ros2dDetect(benchmark::State& s) { ros2d(s, false, false); }
void BM_Ros2dDetectDescribe(benchmark::State& s) { ros2d(s, true, false); }
void BM_Ros2dDetectCappedToSift(benchmark::State& s) { ros2d(s, false, true); }
void BM_Ros2dDetectDescribeCappedToSift(benchmark::State& s) { ros2d(s, true, true); }
void BM_SiftDetect(benchmark::State& s) { sift(s, false); }
void BM_SiftDetectDescribe(benchmark::State& s) { sift(s, true); }

BENCHMARK(BM_Ros2dDetect)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_Ros2dDetectDescribe)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_Ros2dDetectCappedToSift)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_Ros2dDetectDescribeCappedToSift)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_SiftDetect)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_SiftDetectDescribe)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace

int main(int argc, char** argv) {
  // One thread for both: rankslam's front-end runs on one core of two.
  cv::setNumThreads(1);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  if (!frame().empty()) std::printf("frame %d×%d, SIFT keypoints %d\n", frame().cols, frame().rows, sift_count());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
