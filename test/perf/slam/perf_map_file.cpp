// Saving and loading the map file (slam/map_file.hpp) of the simulated office replayed in fused
// mode (300 frames, 16-17 key-frames): SlamLoop::save_map (encode, write, fsync, rename) and
// SlamLoop::load_map (read, verify, decode, rebuild the point map) into a loop set up beforehand,
// and the copy a checkpoint makes on the loop's thread (SlamLoop::snapshot_map).
// Counters: bytes (the file's size), keyframes. The set-up simulates and replays the scene once
// (about 20 s).
//   perf_map_file [benchmark flags]

#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <benchmark/benchmark.h>

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

namespace {

namespace fs = std::filesystem;
using namespace rankslam;

struct Office {
  std::string error;
  fs::path dir;
  replay::Recording recording;
  slam::SlamConfig config;
  std::unique_ptr<slam::SlamLoop> loop;
};

Office& office() {
  static Office s = [] {
    Office o;
    o.dir = fs::temp_directory_path() / ("rankslam_perf_map_file_" + std::to_string(::getpid()));
    fs::remove_all(o.dir);
    sim::SimulationOptions options;
    options.scene = "office";
    options.out_dir = o.dir / "office";
    options.seed = 1;
    o.error = sim::simulate_recording(options, nullptr);
    if (o.error.empty()) o.error = replay::open_recording(options.out_dir, o.recording);
    if (!o.error.empty()) return o;
    o.config.mode = slam::Mode::kFused;
    o.loop = std::make_unique<slam::SlamLoop>(o.config, o.recording.calibration);
    o.loop->set_synchronous_backend(true);
    replay::ReplayDepthCamera camera(o.recording, {});
    o.error = camera.open();
    hal::RgbdFrame frame;
    while (o.error.empty() && camera.read(frame, std::chrono::milliseconds(5000)) == hal::ReadStatus::kOk) {
      (void)o.loop->process(frame);
    }
    o.loop->finish();
    return o;
  }();
  return s;
}

void counters(benchmark::State& state, const Office& o, const fs::path& path) {
  state.counters["bytes"] = static_cast<double>(fs::file_size(path));
  state.counters["keyframes"] = o.loop->keyframe_store().size();
}

void BM_SaveMap(benchmark::State& state) {
  Office& o = office();
  if (!o.error.empty()) return state.SkipWithError(o.error.c_str());
  const fs::path path = o.dir / "office.map";
  for (auto _ : state) {
    if (const std::string error = o.loop->save_map(path); !error.empty()) return state.SkipWithError(error.c_str());
  }
  counters(state, o, path);
}
BENCHMARK(BM_SaveMap)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LoadMap(benchmark::State& state) {
  Office& o = office();
  if (!o.error.empty()) return state.SkipWithError(o.error.c_str());
  const fs::path path = o.dir / "office.map";
  if (const std::string error = o.loop->save_map(path); !error.empty()) return state.SkipWithError(error.c_str());
  slam::SlamLoop loaded(o.config, o.recording.calibration);  // set-up, not timed
  for (auto _ : state) benchmark::DoNotOptimize(loaded.load_map(path));
  counters(state, o, path);
}
BENCHMARK(BM_LoadMap)->Unit(benchmark::kMillisecond)->UseRealTime();

// A checkpoint's share of the loop's thread (SlamLoop::snapshot_map): the first copy into a fresh
// snapshot (every key-frame's features) and a later one with nothing new (poses and the graph),
// against BM_SaveMap above, which the checkpointer's thread then does from the copy.
/// Resident memory of the process, MiB (/proc/self/statm).
double rss_mib() {
  std::ifstream statm("/proc/self/statm");
  long pages = 0;
  long resident = 0;
  statm >> pages >> resident;
  return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
}

void BM_SnapshotFirst(benchmark::State& state) {
  Office& o = office();
  if (!o.error.empty()) return state.SkipWithError(o.error.c_str());
  const double rss_before = rss_mib();
  const std::unique_ptr<slam::MapSnapshot> snapshot = o.loop->make_map_snapshot();
  // The snapshot's memory at set-up (sized for slam.keyframe_capacity key-frames), as the first
  // call finds it: later calls reuse the heap the first one freed.
  static const double snapshot_rss = rss_mib() - rss_before;
  state.counters["snapshot_rss_mib"] = snapshot_rss;
  for (auto _ : state) {
    state.PauseTiming();
    for (int i = 0; i < snapshot->store.capacity(); ++i) snapshot->store.release(i);
    state.ResumeTiming();
    o.loop->snapshot_map(*snapshot);
  }
  state.counters["keyframes"] = snapshot->store.size();
}
BENCHMARK(BM_SnapshotFirst)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SnapshotNothingNew(benchmark::State& state) {
  Office& o = office();
  if (!o.error.empty()) return state.SkipWithError(o.error.c_str());
  const std::unique_ptr<slam::MapSnapshot> snapshot = o.loop->make_map_snapshot();
  o.loop->snapshot_map(*snapshot);
  for (auto _ : state) o.loop->snapshot_map(*snapshot);
  state.counters["keyframes"] = snapshot->store.size();
}
BENCHMARK(BM_SnapshotNothingNew)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  const std::size_t ran = benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  if (ran > 0 && !office().dir.empty()) fs::remove_all(office().dir);
  return 0;
}
