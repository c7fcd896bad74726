// Frames per second of the recording simulator, per scene, including PNG encoding and file
// writing. "setup" runs write a single frame (textures, lightmaps, rays); "run" writes
// kFramesPerRun frames, so steady-state time per frame ≈ (run − setup) / (frames − 1).
// cpu_ms_per_frame is the process CPU time (all threads) per frame: on a shared machine it
// shows the cost independently of how much of the CPU the run actually got.
#include "rankslam/sim/simulator.hpp"

#include <benchmark/benchmark.h>
#include <unistd.h>

#include <ctime>
#include <filesystem>
#include <string>

namespace {

namespace fs = std::filesystem;

double process_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

void simulate(benchmark::State& state, const std::string& scene, int frames, bool motion_blur) {
  const fs::path dir = fs::temp_directory_path() / ("rankslam_perf_sim_" + std::to_string(::getpid()));
  double frames_written = 0.0;
  double cpu_s = 0.0;
  for (auto _ : state) {
    state.PauseTiming();
    fs::remove_all(dir);
    state.ResumeTiming();
    rankslam::sim::SimulationOptions options;
    options.scene = scene;
    options.out_dir = dir;
    options.frames = frames;
    options.motion_blur = motion_blur;
    rankslam::sim::SimulationSummary summary;
    const double cpu_start = process_cpu_s();
    const auto error = rankslam::sim::simulate_recording(options, &summary);
    cpu_s += process_cpu_s() - cpu_start;
    if (!error.empty()) {
      state.SkipWithError(error.c_str());
      break;
    }
    frames_written += summary.frames_written;
  }
  fs::remove_all(dir);
  state.counters["frames_per_second"] = benchmark::Counter(frames_written, benchmark::Counter::kIsRate);
  state.counters["cpu_ms_per_frame"] = frames_written > 0.0 ? 1e3 * cpu_s / frames_written : 0.0;
}

constexpr int kFramesPerRun = 150;

void register_all() {
  for (const std::string scene : {"office", "zigzag-plain", "poster-wall", "dark-office", "corridor-loop"}) {
    benchmark::RegisterBenchmark(("setup/" + scene).c_str(), [scene](benchmark::State& s) { simulate(s, scene, 1, false); })
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(3);
    benchmark::RegisterBenchmark(("run/" + scene).c_str(),
                                 [scene](benchmark::State& s) { simulate(s, scene, kFramesPerRun, false); })
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime()
        ->Iterations(1);
  }
  benchmark::RegisterBenchmark("run_motion_blur/office",
                               [](benchmark::State& s) { simulate(s, "office", 30, true); })
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime()
      ->Iterations(1);
}

}  // namespace

int main(int argc, char** argv) {
  register_all();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
