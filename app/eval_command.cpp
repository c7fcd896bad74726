#include "commands.hpp"
#include "exit_codes.hpp"

#include "rankslam/eval/metrics.hpp"
#include "rankslam/eval/trajectory.hpp"

#include <cstdio>
#include <iostream>

namespace rankslam::app {

int run_eval(const EvalArgs& args) {
  auto ground_truth = eval::read_tum_trajectory(args.ground_truth);
  if (!ground_truth) {
    std::cerr << "error: " << ground_truth.error() << "\n";
    return kExitInput;
  }
  auto estimate = eval::read_tum_trajectory(args.estimate);
  if (!estimate) {
    std::cerr << "error: " << estimate.error() << "\n";
    return kExitInput;
  }
  eval::EvalOptions options;
  options.ate.max_difference_s = args.max_difference_s;
  options.rpe.delta_s = args.delta_s;
  auto result = eval::evaluate(ground_truth.value(), estimate.value(), options);
  if (!result) {
    std::cerr << "error: " << args.estimate.string() << " against " << args.ground_truth.string() << ": "
              << result.error() << "\n";
    return kExitInput;
  }
  std::cout << eval::format_eval_text(result.value());
  // One summary line in the benchmark's customary precision, like `replay` prints.
  std::printf("ATE RMSE %.4f m over %zu pairs\n", result.value().ate.translation_m.rmse,
              result.value().ate.matches.size());
  return kExitOk;
}

}  // namespace rankslam::app
