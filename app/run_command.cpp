// `rankslam run`: live operation. Builds the drivers the robot configuration names, connects
// camera → SLAM loop → pose frames on CAN, and flushes trajectory and map on exit.
#include "checkpointer.hpp"
#include "commands.hpp"
#include "config_file.hpp"
#include "exit_codes.hpp"
#include "frame_pipeline.hpp"
#include "output_frame.hpp"
#include "live_loop.hpp"
#include "robot_config.hpp"
#include "stop_signals.hpp"
#include "wheel_player.hpp"

#include "rankslam/eval/run_report.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/hal/file_set.hpp"
#include "rankslam/hal/nearest_image.hpp"
#include "rankslam/hal/thread_priority.hpp"
#include "rankslam/nav/pose_output.hpp"
#include "rankslam/openni2/openni2_camera.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/slam/slam_loop.hpp"
#include "rankslam/socketcan/socketcan_bus.hpp"
#include "rankslam/systemd/service_notifier.hpp"
#include "rankslam/v4l2/v4l2_camera.hpp"

#include <unistd.h>

#include <atomic>
#include <cmath>
#include <chrono>
#include <cstdio>
#include <future>
#include <iostream>
#include <memory>
#include <optional>
#include <thread>

namespace rankslam::app {

int run_live(const RunArgs& args) {
  namespace fs = std::filesystem;
  RobotConfig robot;
  if (auto error = load_robot_config(args.config, robot); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitInput;
  }
  if (!args.can_interface.empty()) {
    // The unit's instance (rankslam@can0.service) names the interface; it wins over the file,
    // and a disagreement is said, not silent.
    if (robot.can_interface_given && robot.can_interface != args.can_interface) {
      std::cerr << "notice: --can-interface " << args.can_interface << " overrides can.interface "
                << robot.can_interface << " of " << args.config.string() << "\n";
    }
    robot.can_interface = args.can_interface;
    robot.can_interface_given = true;
    std::cout << "can.interface " << args.can_interface << " from --can-interface" << std::endl;
  }
  slam::SlamConfig slam_config;
  nav::WheelOdometryConfig wheel_config;
  if (const int code = load_pipeline_config(args.config, args.mode, slam_config, wheel_config, robot_config_sections());
      code != kExitOk) {
    return code;
  }
  const fs::path out = args.out.empty() ? robot.output_dir : args.out;
  if (out.empty()) {
    std::cerr << "error: " << args.config.string() << ": no output directory (output.dir or --out)\n";
    return kExitUsage;
  }
  if (const int code = make_output_directory(out); code != kExitOk) return code;

  // Under systemd (Type=notify), whose watchdog runs from the start: fed once the camera is open
  // (which can take seconds), by each turn of the loop from READY=1 on.
  systemd::ServiceNotifier notifier;
  const hal::MonotonicClock setup_clock;

  // Set-up: everything that may fail or allocate happens here.
  replay::Recording recording;
  std::unique_ptr<hal::DepthCamera> camera_driver;
  replay::ReplayDepthCamera* replay_camera = nullptr;
  openni2::OpenNI2Camera* openni2_camera = nullptr;
  if (robot.camera_source == CameraSource::kOpenNI2) {
    openni2::OpenNI2Options openni2_options;
    if (auto error = openni2_options_from(robot, openni2_options); !error.empty()) {
      std::cerr << "error: " << args.config.string() << ": camera.calibration: " << error << "\n";
      return kExitInput;
    }
    auto driver = std::make_unique<openni2::OpenNI2Camera>(openni2_options);
    openni2_camera = driver.get();
    camera_driver = std::move(driver);
  } else {
    if (auto error = replay::open_recording(robot.camera_location, recording); !error.empty()) {
      std::cerr << "error: " << args.config.string() << ": camera.source: " << error << "\n";
      return kExitInput;
    }
    for (const auto& warning : recording.warnings) std::cerr << "warning: " << warning << "\n";
    replay::ReplayOptions replay_options;
    replay_options.rate = robot.replay_rate;
    replay_options.max_frames = robot.max_frames;
    auto driver = std::make_unique<replay::ReplayDepthCamera>(recording, replay_options);
    replay_camera = driver.get();
    camera_driver = std::move(driver);
  }
  hal::DepthCamera& camera = *camera_driver;
  if (auto error = camera.open(); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitInput;
  }
  notifier.alive(setup_clock.now_ns());
  // The pose on CAN is the base's: a mounting left to default would put camera axes on the bus.
  hal::Calibration calibration = camera.calibration();
  if (robot.camera_mounting && calibration.rgb.T_base_cam_given) {
    std::cerr << "error: " << args.config.string() << ": camera.mounting is given, and calibration "
              << calibration.source << " gives cameras.rgb.T_base_cam too; keep one\n";
    return kExitInput;
  }
  if (!robot.camera_mounting && !calibration.rgb.T_base_cam_given) {
    std::cerr << "error: " << args.config.string() << ": the camera mounting is unknown: calibration "
              << calibration.source
              << " gives no cameras.rgb.T_base_cam (camera optical frame -> base: x forward, y left, z up). Set "
                 "camera.mounting: {translation: [x, y, z], rotation_xyzw: [x, y, z, w]}, or camera.mounting: identity "
                 "if the base frame is to be the camera's\n";
    return kExitInput;
  }
  if (robot.camera_mounting) {
    calibration.rgb.T_base_cam = *robot.camera_mounting;
    calibration.rgb.T_base_cam_given = true;
  }
  OutputFrame output_frame = OutputFrame::kBase;
  if (auto error = choose_output_frame(args.frame, true, output_frame); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitUsage;
  }
  const Eigen::Isometry3d T_base_cam = calibration.rgb.T_base_cam;
  std::cout << "camera mounting T_base_cam (" << (robot.camera_mounting ? "camera.mounting" : calibration.source)
            << "): " << describe_mounting(T_base_cam) << "; trajectory and map in the " << to_string(output_frame) << " frame\n"
            << std::flush;
  const unsigned wheel_can_id = calibration.wheels ? calibration.wheels->can_id : hal::WheelGeometry{}.can_id;

  {
    // Opening the bus once here turns a missing interface into a start-up error.
    socketcan::SocketCanOptions probe_options;
    probe_options.interface_name = robot.can_interface;
    socketcan::SocketCanBus probe(probe_options);
    if (auto error = probe.open(); !error.empty()) {
      std::cerr << "error: CAN interface " << robot.can_interface << ": " << error << "\n";
      return kExitInput;
    }
    probe.close();
  }

  // The wide-angle camera; one that does not open leaves the run to the RGB-D camera.
  std::unique_ptr<hal::Camera> wide_camera;
  std::string wide_name;
  {
    replay::ReplayOptions wide_options;
    wide_options.rate = robot.replay_rate;
    if (auto error = make_wide_camera(robot, calibration, replay_camera != nullptr ? &recording : nullptr, wide_options,
                                      wide_camera, wide_name);
        !error.empty()) {
      std::cerr << "error: " << args.config.string() << ": " << error << "\n";
      return kExitInput;
    }
  }
  bool wide_open = true;
  std::optional<hal::NearestImage> wide;
  if (wide_camera) {
    if (auto error = wide_camera->open(); !error.empty()) {
      std::cerr << "warning: wide-angle camera " << wide_name << ": " << error
                << "; running on the RGB-D camera alone (heartbeat WideCameraFault)\n";
      wide_open = false;
    }
    wide.emplace(*wide_camera, std::llround(replay::kMaxAssociationGap_s * 1e9));
    wide->allocate(calibration.fisheye->width, calibration.fisheye->height, CV_8UC3);
    // A live camera is read on a thread of its own, however slow the loop; a replay by the loop.
    if (wide_open && dynamic_cast<replay::ReplayStream*>(wide_camera.get()) == nullptr) {
      wide->start_reader(std::chrono::milliseconds(100));
    }
    notifier.alive(setup_clock.now_ns());
  }

  std::cout << "robot configuration " << args.config.string() << "\n"
            << describe_robot_config(robot) << "camera: "
            << (openni2_camera != nullptr ? openni2_camera->describe()
                                          : "replay of " + recording.root.string() + ", " +
                                                std::to_string(replay_camera->frame_count()) + " frames, " +
                                                std::to_string(recording.can_frames.size()) + " CAN frames")
            << ", calibration " << calibration.source << "\n"
            << "wide-angle camera: " << (wide_camera ? wide_name : std::string("none")) << "\n"
            << describe_slam_config(slam_config) << std::flush;


  // Also in the write phase and after it. Without SA_RESTART: a blocking wait in the loop returns
  // at the signal instead of at its timeout.
  defer_stop_signals(false);
  nav::PoseMailbox mailbox;
  std::atomic<bool> stop_output{false};
  // Wheel odometry from the bus as the motion prior: a live camera's stamps and the bus's are
  // both CLOCK_MONOTONIC; a replayed recording's wheel frames are played onto the bus and take
  // their recorded stamps back, the replay camera's clock. A replay without played frames has no
  // wheel clock in common with its camera: no prior.
  const bool play_wheels = replay_camera != nullptr && robot.play_wheel_frames && !recording.can_frames.empty();
  nav::LiveWheels wheels;
  std::string wheels_off_reason;
  if (!calibration.wheels) {
    wheels_off_reason = "the calibration has no wheels section";
  } else if (replay_camera != nullptr && !play_wheels) {
    wheels_off_reason = "the recording's wheel frames are not played";
  } else {
    if (auto error = nav::validate(wheel_config, *calibration.wheels); !error.empty()) {
      std::cerr << "error: wheel odometry: " << error << "\n";
      return kExitInput;
    }
    wheels.enable(wheel_config, *calibration.wheels, T_base_cam, play_wheels ? &recording.can_frames : nullptr);
  }
  std::cout << "wheels: " << (wheels.enabled() ? "CAN frames from " + robot.can_interface + " as the motion prior"
                                               : "not used (" + wheels_off_reason + ")")
            << "\n"
            << (wheels.enabled() ? describe_wheel_config(wheel_config) : std::string()) << std::flush;
  std::optional<WheelPlayer> player;
  ReceivedWheels received_wheels(wheels, player);
  std::optional<wide::Vocabulary> vocabulary;
  if (const int code = load_vocabulary(args.vocabulary, vocabulary); code != kExitOk) return code;
  PipelineOptions pipeline_options;
  pipeline_options.vocabulary = vocabulary ? &*vocabulary : nullptr;
  pipeline_options.max_frames = robot.max_trajectory_poses;
  pipeline_options.recording_clock = replay_camera != nullptr;
  FramePipeline pipeline(slam_config, calibration, wheels.enabled() ? &received_wheels : nullptr, pipeline_options);
  // map.file: yesterday's map when there is one, and where this run's is saved.
  fs::path load_path = args.load_map;
  const fs::path save_path = args.save_map.empty() ? robot.map_file : args.save_map;
  if (load_path.empty() && !robot.map_file.empty()) {
    std::error_code exists_error;
    if (fs::exists(robot.map_file, exists_error)) {
      load_path = robot.map_file;
    } else {
      std::cout << "map.file " << robot.map_file.string() << " does not exist yet: a new map" << std::endl;
    }
  }
  if (!load_path.empty()) {
    if (const int code = pipeline.load_map(load_path); code != kExitOk) return code;
  }
  if (!save_path.empty()) {
    const fs::path dir = save_path.has_parent_path() ? save_path.parent_path() : fs::path(".");
    if (std::error_code dir_error; !fs::is_directory(dir, dir_error)) {
      std::cerr << "error: the map is to be saved to " << save_path.string() << ", but " << dir.string()
                << " is not a directory\n";
      return kExitOutput;
    }
  }
  slam::SlamLoop& loop = pipeline.loop();
  // Checkpoints: the map file and the outputs so far, written by the checkpointer's thread from
  // its copies.
  std::optional<CheckpointWriter> checkpoint_writer;
  std::optional<Checkpointer> checkpointer;
  if (robot.checkpoint_s > 0.0) {
    checkpoint_writer.emplace(slam_config, calibration, save_path, out, output_frame, T_base_cam, RANKSLAM_VERSION);
    checkpointer.emplace(loop, robot.max_trajectory_poses, robot.checkpoint_s, std::ref(*checkpoint_writer));
    std::cout << "checkpoints every " << robot.checkpoint_s << " s: outputs to " << out.string()
              << (save_path.empty() ? std::string() : ", map to " + save_path.string()) << std::endl;
  }

  nav::PoseOutputOptions output_options;
  output_options.broadcast = robot.output;
  output_options.wheel_can_id = wheel_can_id;
  if (wheels.enabled()) output_options.wheel_noise = {wheel_config.wheel_variance_per_m, calibration.wheels->track_width_m};
  nav::PoseOutputCounters pose_counters;
  nav::WheelInputCounters wheel_counters;
  hal::CanBusStatistics bus_statistics;
  std::promise<std::string> realtime_result;
  std::thread sender([&] {
    realtime_result.set_value(robot.output_realtime_priority > 0 ? hal::make_this_thread_realtime(robot.output_realtime_priority)
                                                                 : std::string());
    socketcan::SocketCanOptions options;
    options.interface_name = robot.can_interface;
    options.filters.push_back({wheel_can_id, 0x7FF, false});
    socketcan::SocketCanBus bus(options);
    // open() was checked above on an identical bus; a failure here is counted as faults.
    (void)bus.open();
    const hal::MonotonicClock clock;
    nav::PoseOutput output(output_options, bus, clock, mailbox, wheels);
    output.run(stop_output);
    pose_counters = output.pose_counters();
    wheel_counters = output.wheel_counters();
    bus_statistics = bus.statistics();
    bus.close();
  });

  const std::string realtime_error = realtime_result.get_future().get();
  const int output_priority = realtime_error.empty() ? robot.output_realtime_priority : 0;
  if (!realtime_error.empty()) {
    std::cerr << "warning: output.realtime_priority: " << realtime_error
              << "; the pose output runs with ordinary scheduling and a loaded CPU can delay its cycles\n";
  }
  std::cout << "pose output thread: " << (output_priority > 0 ? "SCHED_FIFO priority " + std::to_string(output_priority) : std::string("ordinary scheduling")) << std::endl;
  std::cout << "vector kernels: " << vector_kernels() << std::endl;

  if (play_wheels) {
    // A frame played before the output thread's socket is bound never reaches it (the first wheel
    // frame, whose stamp starts the odometry, went missing that way under load).
    if (!wheels.wait_receiving(std::chrono::seconds(5))) {
      std::cerr << "warning: the CAN receiver did not start within 5 s; early wheel frames may be missed\n";
    }
    player.emplace(recording.can_frames, robot.can_interface, robot.replay_rate);
    if (auto error = player->start(); !error.empty()) {
      std::cerr << "warning: wheel frames are not played: " << error << "\n";
      player.reset();
    }
  }

  // The service manager learns that set-up is done when the loop starts, and from then on that
  // the loop goes round (WatchdogSec=); the journal gets a status line every interval.
  if (notifier.active()) {
    std::cout << "systemd: notify socket" << (notifier.watchdog_period_ns() > 0
                                                  ? ", watchdog fed every " + std::to_string(notifier.watchdog_period_ns() / 1'000'000) + " ms by the loop"
                                                  : std::string(", no watchdog"))
              << std::endl;
  }
  StatusLine status_line(static_cast<std::int64_t>(robot.status_interval_s * 1e9), STDERR_FILENO);
  LiveLoopParts parts;
  parts.camera = &camera;
  parts.replay_camera = replay_camera;
  parts.pipeline = &pipeline;
  parts.mailbox = &mailbox;
  parts.wheels = wheels.enabled();
  parts.T_base_cam = T_base_cam;
  parts.exit_after_end_s = robot.exit_after_end_s;
  parts.notifier = &notifier;
  parts.status_line = &status_line;
  parts.checkpointer = checkpointer ? &*checkpointer : nullptr;
  parts.wide = wide ? &*wide : nullptr;
  parts.wide_replay = dynamic_cast<replay::ReplayStream*>(wide_camera.get());
  // A lossless replay waits for each frame's image; a live or paced camera is asked for what has come.
  parts.wide_wait = std::chrono::milliseconds(parts.wide_replay != nullptr && robot.replay_rate == 0.0 ? 1000 : 0);
  parts.wide_camera_open = wide_open;
  parts.wide_silence_ns = static_cast<std::int64_t>(robot.output.watchdog_timeout_s * 1e9);
  const bool interrupted = run_live_loop(parts, [] { return stop_requested(); });
  Checkpointer::Counters checkpoint_counters;
  if (checkpointer) {
    checkpointer->stop();
    checkpoint_counters = checkpointer->counters();
    if (checkpoint_counters.failed > 0) {
      std::cerr << "warning: " << checkpoint_counters.failed << " checkpoints failed, the last: "
                << checkpoint_counters.last_error << "\n";
    }
  }

  if (player) player->stop();
  stop_output = true;
  sender.join();
  const replay::ReplayCounters replay_counters = replay_camera != nullptr ? replay_camera->counters() : replay::ReplayCounters{};
  camera.close();
  if (wide) wide->stop_reader();
  if (wide_camera) wide_camera->close();

  // Outputs: one set published at the end, so OUT holds this run's files or the previous run's.
  hal::FileSet outputs(out);
  int exit_code = interrupted ? kExitInterrupted : kExitOk;
  const auto report_error = [&](const std::string& error) {
    if (error.empty()) return;
    std::cerr << "error: " << error << "\n";
    exit_code = kExitOutput;
  };
  // The trajectory is what the pose output sent; the map takes the last optimised key-frame poses.
  pipeline.finish();
  if (!save_path.empty()) {
    const auto start = std::chrono::steady_clock::now();
    if (const std::string error = loop.save_map(save_path); !error.empty()) {
      report_error(error);
    } else {
      std::printf("map saved to %s (%d key-frames, %.1f ms)\n", save_path.string().c_str(), loop.keyframe_store().size(),
                  std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    }
  }
  report_error(outputs.add_written("trajectory.txt", [&](const fs::path& path) {
    return eval::write_tum_trajectory(path, in_output_frame(pipeline.trajectory(), output_frame, T_base_cam));
  }));
  report_error(outputs.add("map.ply", std::string_view(loop.map().to_ply(output_from_world(output_frame, T_base_cam)))));

  eval::JsonWriter json;
  json.begin_object();
  eval::write_report_header(json, RANKSLAM_VERSION, "run");
  json.string("config", args.config.string());
  json.string("output_frame", to_string(output_frame));
  json.integer("keyframes", loop.keyframes());
  json.integer("loop_closures", loop.loop_closures());
  json.integer("loop_closures_refuted", loop.loop_closures_refuted());
  write_local_map(json, loop);
  json.number("peak_rss_mb", peak_rss_mb());
  json.string("vector_kernels", vector_kernels());
  json.string("camera", (openni2_camera != nullptr ? "openni2:" + robot.camera_location : "replay:" + recording.root.string()));
  if (openni2_camera != nullptr) {
    const openni2::OpenNI2Counters& c = openni2_camera->counters();
    json.integer("camera_device_dropped", static_cast<long long>(c.dropped));
    json.integer("camera_unpaired", static_cast<long long>(c.unpaired));
    json.integer("camera_faults", static_cast<long long>(c.faults));
    json.integer("camera_reopens", static_cast<long long>(c.reopens));
  }
  if (wide) {
    json.begin_object("wide_angle");
    json.string("camera", wide_name);
    json.boolean("opened", wide_open);
    json.integer("images", static_cast<long long>(wide->counters().read));
    json.integer("paired", static_cast<long long>(wide->counters().paired));
    json.integer("faults", static_cast<long long>(wide->counters().faults));
    if (const auto* device = dynamic_cast<const v4l2::V4l2Camera*>(wide_camera.get()); device != nullptr) {
      json.integer("device_dropped", static_cast<long long>(device->counters().dropped));
      json.integer("device_corrupt", static_cast<long long>(device->counters().corrupt));
    }
    json.end_object();
  } else {
    json.null("wide_angle");
  }
  json.string("can_interface", robot.can_interface);
  json.integer("frames", static_cast<long long>(pipeline.frames()));
  json.integer("failed_frames", pipeline.failed_frames());
  // The sender has stopped: the wheels need no lock any more.
  eval::write_status_and_wheels(json, pipeline.status_counts(), wheels.prior(), loop.wheel_slip_events(),
                          wheels_off_reason);
  if (wheels.enabled()) json.integer("wheel_frames_unmatched", static_cast<long long>(wheel_counters.unmatched));
  json.integer("skipped_frames", replay_counters.corrupt);
  json.integer("dropped_frames", replay_counters.dropped);
  json.integer("trajectory_overflow", static_cast<long long>(pipeline.trajectory_overflow()));
  json.integer("pose_cycles", static_cast<long long>(pose_counters.pose_cycles));
  json.integer("lost_cycles", static_cast<long long>(pose_counters.lost_cycles));
  json.integer("heartbeats", static_cast<long long>(pose_counters.heartbeats));
  json.integer("pose_output_realtime_priority", output_priority);
  json.integer("tx_dropped", static_cast<long long>(pose_counters.tx_dropped));
  json.integer("tx_faults", static_cast<long long>(pose_counters.tx_faults));
  json.integer("wheel_frames_played", player ? static_cast<long long>(player->sent()) : 0LL);
  json.integer("wheel_frames_received", static_cast<long long>(wheel_counters.frames));
  json.integer("wheel_counter_gaps", static_cast<long long>(wheel_counters.counter_gaps));
  json.integer("bus_frames_tx", static_cast<long long>(bus_statistics.frames_tx));
  json.integer("bus_error_frames", static_cast<long long>(bus_statistics.error_frames));
  json.integer("bus_faults", static_cast<long long>(bus_statistics.faults));
  json.string("map_file", save_path.string());
  json.integer("checkpoints_written", static_cast<long long>(checkpoint_counters.written));
  json.integer("checkpoints_skipped", static_cast<long long>(checkpoint_counters.skipped));
  json.integer("checkpoint_failures", static_cast<long long>(checkpoint_counters.failed));
  json.boolean("interrupted", interrupted);
  json.end_object();
  report_error(outputs.add("report.json", std::string_view(json.str())));
  report_error(outputs.publish());
  if (exit_code == kExitOk && stop_requested()) exit_code = kExitInterrupted;

  std::printf("frames %llu  failed %d  pose cycles %llu (lost %llu)  heartbeats %llu  wheel frames in %llu%s\n",
              static_cast<unsigned long long>(pipeline.frames()), pipeline.failed_frames(), static_cast<unsigned long long>(pose_counters.pose_cycles),
              static_cast<unsigned long long>(pose_counters.lost_cycles),
              static_cast<unsigned long long>(pose_counters.heartbeats),
              static_cast<unsigned long long>(wheel_counters.frames), interrupted ? "  (interrupted)" : "");
  std::printf("outputs in %s\n", out.string().c_str());
  return exit_code;
}

}  // namespace rankslam::app
