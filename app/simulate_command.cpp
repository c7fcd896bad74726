#include "commands.hpp"
#include "exit_codes.hpp"

#include "rankslam/sim/simulator.hpp"

#include <cstdio>
#include <iostream>

namespace rankslam::app {

int run_simulate(const SimulateArgs& args) {
  sim::SimulationOptions options;
  options.scene = args.scene;
  options.out_dir = args.out;
  options.frames = args.frames;
  options.seed = args.seed;
  options.scene_seed = args.scene_seed;
  options.motion_blur = args.motion_blur;
  sim::SimulationSummary summary{};
  if (auto error = sim::simulate_recording(options, &summary); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitInput;
  }
  std::printf("simulated %s: %d frames in %.2f s (%.1f frames/s) into %s\n", summary.scene.c_str(),
              summary.frames_written, summary.seconds, summary.frames_per_second, args.out.string().c_str());
  return kExitOk;
}

}  // namespace rankslam::app
