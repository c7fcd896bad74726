#include "commands.hpp"
#include "exit_codes.hpp"

#include "rankslam/eval/plot.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/features/extractor.hpp"
#include "rankslam/hal/file_set.hpp"
#include "rankslam/stereo/sequence.hpp"

#include <cstdio>
#include <iostream>

namespace rankslam::app {

int run_stereo_vo(const StereoVoArgs& args) {
  auto dataset = stereo::read_stereo_dataset(args.dataset, args.ground_truth);
  if (!dataset) {
    std::cerr << "error: " << dataset.error() << "\n";
    return kExitInput;
  }
  if (const std::string error = hal::prepare_output_directory(args.out); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitOutput;
  }
  stereo::StereoOdometryConfig config;
  config.features.kind = *features::parse_feature_kind(args.features);  // CLI11 checked the name
  config.bundle_adjustment = !args.no_ba;
  if (args.seed != 0) config.msse.seed = args.seed;
  stereo::SequenceOptions options;
  options.max_frames = args.max_frames;
  std::printf("stereo-vo: %zu pairs of %s, features %s, window bundle adjustment %s\n", dataset.value().frames.size(),
              args.dataset.string().c_str(), args.features.c_str(), args.no_ba ? "off" : "on");

  auto run = stereo::run_stereo_sequence(dataset.value(), config, options);
  if (!run) {
    std::cerr << "error: " << run.error() << "\n";
    return kExitInput;
  }
  for (const auto& warning : run.value().warnings) std::cerr << "warning: " << warning << "\n";
  const stereo::StereoAccuracy accuracy = stereo::evaluate_stereo_run(run.value(), dataset.value().ground_truth);

  // One set published at the end, so OUT holds this run's files or the previous run's.
  hal::FileSet outputs(args.out);
  int exit_code = kExitOk;
  const auto report_error = [&](const std::string& error) {
    if (error.empty()) return;
    std::cerr << "error: " << error << "\n";
    exit_code = kExitOutput;
  };
  report_error(outputs.add_written("trajectory.txt", [&](const std::filesystem::path& path) {
    return eval::write_tum_trajectory(path, run.value().trajectory);
  }));
  report_error(outputs.add("report.json", std::string_view(stereo::stereo_report_json(
                                              dataset.value(), args.dataset, config, run.value(), accuracy))));
  eval::TopViewOptions plot_options;
  plot_options.title = "stereo-vo " + args.features + (args.no_ba ? " (no BA)" : " (window BA)");
  if (accuracy.eval) plot_options.ate_rmse_m = accuracy.eval->ate.translation_m.rmse;
  const cv::Mat plot = eval::render_top_view(
      run.value().trajectory, dataset.value().ground_truth ? &*dataset.value().ground_truth : nullptr, plot_options);
  report_error(outputs.add_written("trajectory.png", [&](const std::filesystem::path& path) { return eval::write_png(path, plot); }));
  report_error(outputs.publish());

  std::cout << stereo::format_stereo_summary(run.value(), accuracy);
  std::printf("outputs in %s\n", args.out.string().c_str());
  return exit_code;
}

}  // namespace rankslam::app
