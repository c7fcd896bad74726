#include "commands.hpp"
#include "config_file.hpp"
#include "output_frame.hpp"
#include "exit_codes.hpp"
#include "frame_pipeline.hpp"
#include "progress.hpp"
#include "robot_config.hpp"
#include "stop_signals.hpp"
#include "rankslam/nav/wheel_frame.hpp"
#include "rankslam/nav/wheel_prior.hpp"

#include "rankslam/core/stopwatch.hpp"
#include "rankslam/eval/metrics.hpp"
#include "rankslam/eval/plot.hpp"
#include "rankslam/eval/run_report.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/hal/file_set.hpp"
#include "rankslam/hal/nearest_image.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/replay/replay_can_bus.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/slam/slam_loop.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <optional>
#include <vector>

namespace rankslam::app {

int run_replay(const ReplayArgs& args) {
  namespace fs = std::filesystem;
  slam::SlamConfig config;
  nav::WheelOdometryConfig wheel_config;
  if (const int code = load_pipeline_config(args.config, args.mode, config, wheel_config); code != kExitOk) return code;
  if (const int code = make_output_directory(args.out); code != kExitOk) return code;

  fs::path recording_dir = args.recording;
  if (recording_dir.empty()) {
    recording_dir = args.out / "recording";
    std::error_code ec;
    const bool occupied = fs::exists(fs::symlink_status(recording_dir, ec)) &&
                          !(fs::is_directory(recording_dir, ec) && fs::is_empty(recording_dir, ec));
    if (occupied) {
      // Nothing already there is deleted: the default scene simulated by an earlier run is replayed again.
      if (!sim::is_simulated_recording(recording_dir, kDefaultScene)) {
        std::cerr << "error: no recording given and " << recording_dir.string()
                  << " holds something other than the simulated default scene; give a recording or another --out\n";
        return kExitOutput;
      }
      if (!args.quiet) {
        std::cout << "no recording given: replaying the '" << kDefaultScene << "' scene simulated in " << recording_dir
                  << "\n";
      }
    } else {
      if (!args.quiet) {
        std::cout << "no recording given: simulating the '" << kDefaultScene << "' scene into " << recording_dir << "\n";
      }
      SimulateArgs simulate;
      simulate.scene = kDefaultScene;
      simulate.out = recording_dir;
      if (const int code = run_simulate(simulate); code != kExitOk) return code;
    }
  }

  replay::Recording recording;
  if (auto error = replay::open_recording(recording_dir, recording); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitInput;
  }
  for (const auto& warning : recording.warnings) std::cerr << "warning: " << warning << "\n";
  const hal::CameraCalibration& rgb = recording.calibration.rgb;
  OutputFrame output_frame = OutputFrame::kCamera;
  if (auto error = choose_output_frame(args.frame, rgb.T_base_cam_given, output_frame); !error.empty()) {
    std::cerr << "error: " << recording.calibration.source << ": " << error << "\n";
    return kExitUsage;
  }

  replay::ReplayOptions options;
  options.rate = args.rate;
  options.max_frames = args.max_frames;
  options.decode_ahead = args.decode_ahead;
  replay::ReplayDepthCamera camera(recording, options);
  if (auto error = camera.open(); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitInput;
  }
  if (!args.quiet) {
    std::cout << "recording " << recording.root.string() << ": " << camera.frame_count() << " frames, calibration "
              << recording.calibration.source << "\n"
              << "camera mounting T_base_cam: "
              << (rgb.T_base_cam_given ? describe_mounting(rgb.T_base_cam) : std::string("unknown")) << "; outputs in the "
              << to_string(output_frame) << " frame\n"
              << describe_slam_config(config);
  }

  // The wide-angle camera's images, paired with the colour frames by nearest stamp, where the
  // SLAM reads them. All of them are read: the pairing stops where the colour frames end.
  const std::unique_ptr<replay::ReplayImageCamera> wide_camera =
      config.wide.enabled() ? make_replay_wide_camera(recording, options) : nullptr;
  if (!wide_camera && !args.quiet && !recording.fisheye.empty()) {
    std::cout << "wide-angle camera: " << recording.fisheye.size()
              << " images, not read (slam.wide_*_candidates are 0)\n";
  }
  std::optional<hal::NearestImage> wide;
  if (wide_camera) {
    if (auto error = wide_camera->open(); !error.empty()) {
      std::cerr << "error: " << error << "\n";
      return kExitInput;
    }
    wide.emplace(*wide_camera, std::llround(replay::kMaxAssociationGap_s * 1e9));
    wide->allocate(recording.calibration.fisheye->width, recording.calibration.fisheye->height, CV_8UC3);
    if (!args.quiet) {
      std::cout << "wide-angle camera: " << wide_camera->frame_count() << " images, paired with frames within "
                << replay::kMaxAssociationGap_s << " s\n";
    }
  }
  // A lossless replay waits for the image after each frame; a paced one takes what has arrived.
  const auto wide_wait = std::chrono::milliseconds(args.rate > 0.0 ? 0 : 1000);

  // Wheel odometry from the recording's can.log, when it has one and the calibration describes
  // the wheels: the prior of every frame.
  std::optional<nav::WheelPrior> wheels;
  std::string wheels_off_reason;
  if (args.no_wheels) {
    wheels_off_reason = "--no-wheels";
  } else if (recording.can_frames.empty()) {
    wheels_off_reason = "no can.log";
  } else if (!recording.calibration.wheels) {
    wheels_off_reason = "the calibration has no wheels section";
  } else {
    if (auto error = nav::validate(wheel_config, *recording.calibration.wheels); !error.empty()) {
      std::cerr << "error: " << recording.calibration.source << ": " << error << "\n";
      return kExitInput;
    }
    wheels.emplace(wheel_config, *recording.calibration.wheels, recording.calibration.rgb.T_base_cam);
    if (auto malformed = nav::describe_malformed_wheel_frames(recording.can_frames, recording.calibration.wheels->can_id);
        !malformed.empty()) {
      std::cerr << "warning: " << (recording.root / "can.log").string() << ": " << malformed << "\n";
    }
  }
  if (!args.quiet) {
    std::cout << "wheels: "
              << (wheels ? std::to_string(recording.can_frames.size()) + " CAN frames from can.log as the motion prior"
                         : "not used (" + wheels_off_reason + ")")
              << "\n"
              << (wheels ? describe_wheel_config(wheel_config) : std::string());
  }
  // The recording's CAN frames reach the odometry through a bus, as a live base's do.
  replay::ReplayCanBus can_bus(recording.can_frames, {recording.calibration.wheels.value_or(hal::WheelGeometry{}).can_id});
  if (auto error = can_bus.open(); !error.empty()) {
    std::cerr << "error: " << recording.root.string() << "/can.log: " << error << "\n";
    return kExitInput;
  }
  std::optional<ReplayedWheels> replayed_wheels;
  if (wheels) replayed_wheels.emplace(can_bus, *wheels);

  std::optional<wide::Vocabulary> vocabulary;
  if (const int code = load_vocabulary(args.vocabulary, vocabulary); code != kExitOk) return code;
  PipelineOptions pipeline_options;
  pipeline_options.vocabulary = vocabulary ? &*vocabulary : nullptr;
  pipeline_options.max_frames = camera.frame_count();
  pipeline_options.recording_clock = true;
  // Offline: each pose-graph solve is waited for, so a replay gives the same result every time.
  pipeline_options.synchronous_backend = true;
  pipeline_options.frame_log = true;
  FramePipeline pipeline(config, recording.calibration, replayed_wheels ? &*replayed_wheels : nullptr, pipeline_options);
  if (!args.load_map.empty()) {
    if (const int code = pipeline.load_map(args.load_map); code != kExitOk) return code;
  }
  slam::SlamLoop& loop = pipeline.loop();

  // Also in the write phase and after it: a signal then is deferred, not fatal.
  defer_stop_signals(true);
  ProgressLine progress(camera.frame_count());
  hal::RgbdFrame frame;
  bool interrupted = false;
  for (;;) {
    if (stop_requested()) {
      interrupted = true;
      break;
    }
    const hal::ReadStatus status = camera.read(frame, std::chrono::milliseconds(1000));
    for (const auto& warning : camera.take_warnings()) std::cerr << "\nwarning: " << warning << "\n";
    if (status == hal::ReadStatus::kEndOfStream) break;
    if (status != hal::ReadStatus::kOk) continue;
    const hal::ImageFrame* paired = nullptr;
    if (wide) {
      paired = wide->take(frame.stamp_ns, wide_wait);
      for (const auto& warning : wide_camera->take_warnings()) std::cerr << "\nwarning: " << warning << "\n";
    }
    (void)pipeline.process(frame, paired);
    progress.update(static_cast<unsigned>(pipeline.frames()));
  }
  progress.finish();
  // The last optimisation, then every frame re-expressed on its key-frame's optimised pose.
  pipeline.finish();
  const eval::Trajectory& estimate = pipeline.trajectory();
  const std::vector<slam::LoopClosure>& closures = pipeline.closures();
  const int failed_frames = pipeline.failed_frames();
  const replay::ReplayCounters counters = camera.counters();
  for (const auto& warning : camera.take_warnings()) std::cerr << "warning: " << warning << "\n";
  camera.close();
  std::optional<replay::ReplayCounters> wide_counters;
  if (wide_camera) {
    wide_camera->close();
    for (const auto& warning : wide_camera->take_warnings()) std::cerr << "warning: " << warning << "\n";
    wide_counters = wide_camera->counters();
  }
  if (!interrupted && counters.delivered == 0) {
    std::cerr << "error: no frame of " << recording.root.string() << " could be read (" << counters.corrupt
              << " skipped, see the warnings above)\n";
    return kExitInput;
  }

  // Outputs: one set published at the end, so OUT holds this run's files or the previous run's.
  hal::FileSet outputs(args.out);
  int exit_code = interrupted ? kExitInterrupted : kExitOk;
  const auto report_error = [&](const std::string& error) {
    if (error.empty()) return;
    std::cerr << "error: " << error << "\n";
    exit_code = kExitOutput;
  };
  report_error(outputs.add_written("trajectory.txt", [&](const fs::path& path) {
    return eval::write_tum_trajectory(path, in_output_frame(estimate, output_frame, rgb.T_base_cam));
  }));
  report_error(outputs.add("map.ply", std::string_view(loop.map().to_ply(output_from_world(output_frame, rgb.T_base_cam)))));

  std::optional<eval::EvalResult> accuracy;
  std::optional<eval::Trajectory> ground_truth;
  std::string no_accuracy_reason = "no ground truth";
  if (recording.ground_truth) {
    auto gt = eval::read_tum_trajectory(*recording.ground_truth);
    no_accuracy_reason = "see the warning above";
    if (!gt) {
      std::cerr << "warning: " << gt.error() << "; no accuracy computed\n";
    } else {
      ground_truth = std::move(gt).value();
      auto evaluated = eval::evaluate(*ground_truth, estimate);
      if (evaluated) {
        accuracy = std::move(evaluated).value();
      } else {
        std::cerr << "warning: " << evaluated.error() << "; no accuracy computed\n";
      }
    }
  }
  // The odom pose's error against the ground truth beside the sigmas sent with it.
  std::vector<eval::FrameRecord> frame_records = pipeline.frame_records();
  if (ground_truth) eval::add_odom_errors(frame_records, *ground_truth, recording.calibration.rgb.T_base_cam);
  const eval::SigmaCoverage coverage = eval::sigma_coverage(frame_records);
  report_error(outputs.add("frames.csv", std::string_view(eval::frames_csv(frame_records))));
  std::vector<eval::RelativePoseError> closure_errors;
  if (ground_truth && !closures.empty()) {
    std::vector<eval::StampedRelativePose> measured;
    measured.reserve(closures.size());
    for (const slam::LoopClosure& c : closures) measured.push_back({c.stored_stamp_s, c.current_stamp_s, c.T_stored_current});
    auto errors = eval::compute_relative_pose_errors(*ground_truth, measured);
    if (errors) {
      closure_errors = std::move(errors).value();
    } else {
      std::cerr << "warning: " << errors.error() << "; loop closures not checked against the ground truth\n";
    }
  }
  report_error(outputs.add("loop_closures.csv", std::string_view(eval::loop_closures_csv(closures, closure_errors))));
  // The wide-angle camera's RGBD–mono edges against the ground truth, as the closures are.
  int checked_wide_edges = 0;
  int false_wide_edges = 0;
  double worst_wide_edge_m = 0.0;
  std::vector<eval::RelativePoseError> wide_edge_errors;
  if (ground_truth && !pipeline.wide_edges().empty()) {
    std::vector<eval::StampedRelativePose> measured;
    measured.reserve(pipeline.wide_edges().size());
    for (const slam::LoopClosure& e : pipeline.wide_edges()) measured.push_back({e.stored_stamp_s, e.current_stamp_s, e.T_stored_current});
    if (auto errors = eval::compute_relative_pose_errors(*ground_truth, measured)) {
      wide_edge_errors = std::move(errors).value();
    } else {
      std::cerr << "warning: " << errors.error() << "; wide-angle edges not checked against the ground truth\n";
    }
  }
  for (const eval::RelativePoseError& error : wide_edge_errors) {
    if (!error.has_ground_truth) continue;
    ++checked_wide_edges;
    false_wide_edges += eval::is_false_closure(error) ? 1 : 0;
    worst_wide_edge_m = std::max(worst_wide_edge_m, error.translation_m);
  }
  if (loop.wide_counters() != nullptr) {
    report_error(outputs.add("wide_edges.csv", std::string_view(eval::loop_closures_csv(pipeline.wide_edges(), wide_edge_errors))));
  }
  int checked_closures = 0;
  int false_closures = 0;
  double worst_closure_m = 0.0;
  double worst_closure_deg = 0.0;
  for (const eval::RelativePoseError& error : closure_errors) {
    if (!error.has_ground_truth) continue;
    ++checked_closures;
    false_closures += eval::is_false_closure(error) ? 1 : 0;
    worst_closure_m = std::max(worst_closure_m, error.translation_m);
    worst_closure_deg = std::max(worst_closure_deg, error.rotation_deg);
  }
  {
    eval::TopViewOptions plot_options;
    plot_options.title = recording.root.filename().string() + "  (" + std::string(slam::to_string(config.mode)) + ")";
    if (accuracy) plot_options.ate_rmse_m = accuracy->ate.translation_m.rmse;
    const cv::Mat plot = eval::render_top_view(estimate, ground_truth ? &*ground_truth : nullptr, plot_options);
    report_error(outputs.add_written("trajectory.png", [&](const fs::path& path) { return eval::write_png(path, plot); }));
  }

  eval::JsonWriter json;
  json.begin_object();
  eval::write_report_header(json, RANKSLAM_VERSION, "replay");
  json.string("recording", recording.root.string());
  json.string("output_frame", to_string(output_frame));
  json.string("mode", slam::to_string(config.mode));
  json.integer("frames", static_cast<long long>(pipeline.frames()));
  json.integer("failed_frames", failed_frames);
  json.integer("skipped_frames", counters.corrupt);
  json.integer("dropped_frames", counters.dropped);
  json.boolean("decode_ahead", args.decode_ahead);
  eval::write_status_and_wheels(json, pipeline.status_counts(), wheels ? &*wheels : nullptr, loop.wheel_slip_events(), wheels_off_reason);
  if (wide) {
    json.begin_object("wide_angle");
    json.integer("images", static_cast<long long>(wide->counters().read));
    json.integer("paired", static_cast<long long>(wide->counters().paired));
    json.integer("skipped", wide_counters->corrupt);
    if (const slam::WideCounters* used = loop.wide_counters(); used != nullptr) {
      json.integer("used", static_cast<long long>(used->images));
      json.integer("dropped", static_cast<long long>(used->dropped));
      json.integer("mono_nodes", static_cast<long long>(used->mono_nodes));
      json.integer("rgbd_mono_edges", static_cast<long long>(used->edges));
      json.integer("loop_edges", static_cast<long long>(used->loop_edges));
      json.integer("refused_edges", static_cast<long long>(used->refused));
      if (checked_wide_edges > 0) {
        json.integer("edges_checked", checked_wide_edges);
        json.integer("false_edges", false_wide_edges);
        json.number("worst_edge_m", worst_wide_edge_m);
      }
    }
    json.end_object();
  } else {
    json.null("wide_angle");
  }
  json.integer("keyframes", loop.keyframes());
  json.integer("loop_closures", loop.loop_closures());
  json.integer("loop_closures_refuted", loop.loop_closures_refuted());
  write_local_map(json, loop);
  if (checked_closures > 0) {
    json.integer("loop_closures_checked", checked_closures);
    json.integer("false_loop_closures", false_closures);
    json.number("loop_closure_max_error_m", worst_closure_m);
    json.number("loop_closure_max_error_deg", worst_closure_deg);
  } else {
    json.integer("loop_closures_checked", 0);
    json.null("false_loop_closures").null("loop_closure_max_error_m").null("loop_closure_max_error_deg");
  }
  json.integer("relocalisations", loop.relocalisations());
  const std::vector<eval::RelocalisationRecord>& relocalisations = pipeline.relocalisations();
  if (relocalisations.empty()) {
    json.null("relocalised_at_frame");
  } else {
    json.integer("relocalised_at_frame", static_cast<long long>(relocalisations.front().frame));
  }
  if (accuracy && !relocalisations.empty()) {
    const std::vector<eval::RelocalisationError> errors =
        eval::relocalisation_errors(*ground_truth, accuracy->ate, relocalisations, eval::kDefaultMaxDifference_s);
    if (errors.front().has_ground_truth) {
      json.number("relocalisation_error_m", errors.front().translation_m);
    } else {
      json.null("relocalisation_error_m");
    }
    json.integer("false_relocalisations", static_cast<long long>(std::count_if(
                                              errors.begin(), errors.end(), eval::is_false_relocalisation)));
  } else {
    json.null("relocalisation_error_m").null("false_relocalisations");
  }
  json.integer("retired_keyframes", loop.retired_keyframes());
  json.number("peak_rss_mb", peak_rss_mb());
  json.string("vector_kernels", vector_kernels());
  json.integer("map_points", static_cast<long long>(loop.map().size()));
  json.boolean("interrupted", interrupted);
  if (accuracy) {
    json.number("ate_rmse_m", accuracy->ate.translation_m.rmse);
    json.number("ate_mean_m", accuracy->ate.translation_m.mean);
    json.number("ate_median_m", accuracy->ate.translation_m.median);
    json.number("ate_max_m", accuracy->ate.translation_m.max);
    if (accuracy->rpe) {
      json.number("rpe_trans_m_per_s", accuracy->rpe->translation_m_per_s.rmse);
      json.number("rpe_rot_deg_per_s", accuracy->rpe->rotation_deg_per_s.rmse);
    } else {
      json.null("rpe_trans_m_per_s").null("rpe_rot_deg_per_s");
    }
  } else {
    json.null("ate_rmse_m").null("rpe_trans_m_per_s").null("rpe_rot_deg_per_s");
  }
  if (coverage.frames > 0) {
    json.begin_object("pose_sigma");
    json.integer("frames", coverage.frames);
    json.number("position_coverage_3sigma", coverage.position_coverage);
    json.number("yaw_coverage_3sigma", coverage.yaw_coverage);
    json.number("median_position_sigma_m", coverage.median_position_sigma_m);
    json.number("median_position_error_m", coverage.median_position_error_m);
    json.number("median_yaw_sigma_deg", coverage.median_yaw_sigma_deg);
    json.number("median_yaw_error_deg", coverage.median_yaw_error_deg);
    json.end_object();
  } else {
    json.null("pose_sigma");
  }
  eval::write_percentiles(json, "frame_ms", eval::percentiles(pipeline.frame_ms()));
  json.begin_object("stage_ms");
  for (std::size_t i = 0; i < slam::StageTimes::kCount; ++i) {
    eval::write_percentiles(json, slam::StageTimes::kNames[i], eval::percentiles(pipeline.stage_ms()[i]));
  }
  json.end_object();
  json.string("calibration", recording.calibration.source);
  json.raw_object("config", slam_config_json(config));
  json.end_object();
  report_error(outputs.add("report.json", std::string_view(json.str())));
  report_error(outputs.publish());
  if (exit_code == kExitOk && stop_requested()) exit_code = kExitInterrupted;

  const eval::Percentiles timing = eval::percentiles(pipeline.frame_ms());
  std::printf("frames %llu  failed %d  skipped %u  median %.1f ms/frame (vector kernels %s)\n",
              static_cast<unsigned long long>(pipeline.frames()), failed_frames,
              counters.corrupt, timing.median, vector_kernels().c_str());
  std::printf("status TRACKING %d  DEGRADED %d  LOST %d", pipeline.status_counts().tracking, pipeline.status_counts().degraded,
              pipeline.status_counts().lost);
  if (wheels) {
    std::printf("  wheel slip events %d  wheel/vision disagreements %d\n", loop.wheel_slip_events(),
                pipeline.status_counts().disagreements);
  } else {
    std::printf("  (no wheels: %s)\n", wheels_off_reason.c_str());
  }
  if (wide) {
    std::printf("wide-angle images %llu  paired with frames %llu  skipped %u",
                static_cast<unsigned long long>(wide->counters().read),
                static_cast<unsigned long long>(wide->counters().paired), wide_counters->corrupt);
    if (const slam::WideCounters* used = loop.wide_counters(); used != nullptr) {
      std::printf("  used %llu  mono nodes %llu  RGBD-mono edges %llu (%llu to older key-frames, %llu refused)",
                  static_cast<unsigned long long>(used->images), static_cast<unsigned long long>(used->mono_nodes),
                  static_cast<unsigned long long>(used->edges), static_cast<unsigned long long>(used->loop_edges),
                  static_cast<unsigned long long>(used->refused));
      if (checked_wide_edges > 0) std::printf("  against the ground truth: %d false, worst %.3f m", false_wide_edges, worst_wide_edge_m);
    } else {
      std::printf("  (not used: slam.wide_*_candidates are 0)");
    }
    std::printf("\n");
  }
  std::printf("loop closures %d (%d refuted by their neighbours)", loop.loop_closures(), loop.loop_closures_refuted());
  if (checked_closures > 0) {
    std::printf("  against the ground truth: %d false, worst %.3f m %.2f deg", false_closures, worst_closure_m,
                worst_closure_deg);
  }
  std::printf("\n");
  if (accuracy) {
    std::printf("ATE RMSE %.4f m", accuracy->ate.translation_m.rmse);
    if (accuracy->rpe) {
      std::printf("  RPE %.4f m/s %.3f deg/s", accuracy->rpe->translation_m_per_s.rmse,
                  accuracy->rpe->rotation_deg_per_s.rmse);
    }
    std::printf("\n");
  } else {
    std::printf("ATE n/a (%s)\n", no_accuracy_reason.c_str());
  }
  if (coverage.frames > 0) {
    std::printf("odom pose within 3 sigma: position %.1f %%, yaw %.1f %% of %d frames (median sigma %.4f m, error %.4f m)\n",
                100.0 * coverage.position_coverage, 100.0 * coverage.yaw_coverage, coverage.frames,
                coverage.median_position_sigma_m, coverage.median_position_error_m);
  }
  std::printf("outputs in %s\n", args.out.string().c_str());
  if (!args.save_map.empty()) {
    const auto save_start = SteadyClock::now();
    if (const std::string error = loop.save_map(args.save_map); !error.empty()) {
      report_error(error);
    } else {
      std::error_code size_error;
      std::printf("map saved to %s (%d key-frames, %ju bytes, %.1f ms)\n", args.save_map.string().c_str(),
                  loop.keyframe_store().size(), static_cast<std::uintmax_t>(fs::file_size(args.save_map, size_error)),
                  elapsed_ms(save_start));
    }
  }
  return exit_code;
}

}  // namespace rankslam::app
