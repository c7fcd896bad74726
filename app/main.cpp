// rankslam command line: builds the parts each subcommand needs and runs it. No algorithm here.
// GCC 12 reports a null dereference inside CLI11's string splitting as inlined here, a false
// positive of the middle end that a pragma around the include cannot reach.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wnull-dereference"
#endif
#include "commands.hpp"
#include "exit_codes.hpp"

#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"

#include <CLI/CLI.hpp>

#include <exception>
#include <iostream>

int main(int argc, char** argv) {
  using namespace rankslam::app;
  CLI::App app{"rankslam: RGB-D SLAM for robots in texture-less, structure-less and dark places"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "rankslam " RANKSLAM_VERSION);

  ReplayArgs replay;
  auto* replay_cmd = app.add_subcommand("replay", "Run the SLAM loop over a recording and write trajectory, map, plot and report");
  replay_cmd->add_option("recording", replay.recording,
                         "Recording directory (TUM RGB-D layout); without it the built-in default scene is simulated and replayed");
  replay_cmd->add_option("--out,-o", replay.out, "Output directory")->required();
  replay_cmd->add_option("--mode,-m", replay.mode, "Registration: baseline, photometric, geometric or fused (default: fused)");
  replay_cmd->add_option("--config,-c", replay.config, "YAML configuration (see deploy/config/default.yaml)");
  replay_cmd->add_option("--rate", replay.rate, "Play at this multiple of the recorded rate, dropping frames the loop cannot keep up with (0 = as fast as possible, lossless)")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            double rate = 0.0;
            // Slower or faster, the replay's pacing would overflow its clock.
            if (CLI::detail::lexical_cast(text, rate) &&
                (rate == 0.0 || (rate >= rankslam::replay::kMinReplayRate && rate <= rankslam::replay::kMaxReplayRate))) {
              return {};
            }
            return "--rate must be 0 (as fast as possible) or between " + std::to_string(rankslam::replay::kMinReplayRate) +
                   " and " + std::to_string(rankslam::replay::kMaxReplayRate) + ", not " + text;
          },
          "0 or 0.001..1000"));
  replay_cmd->add_option("--max-frames", replay.max_frames, "Replay at most this many frames (0 = all)");
  replay_cmd->add_flag("--quiet,-q", replay.quiet, "Print only the summary");
  replay_cmd->add_option("--frame", replay.frame, "Frame of trajectory.txt and map.ply: base (the map frame of the base, x forward, z up; the default when the calibration gives T_base_cam) or camera (the first camera's optical frame)")
      ->check(CLI::IsMember({"camera", "base"}));
  replay_cmd->add_flag("--decode-ahead", replay.decode_ahead, "Decode the next frames while the loop runs: a faster replay, but decoding then competes with the loop for the cores and its timings include that (without it, as on the robot, they do not)");
  replay_cmd->add_option("--save-map", replay.save_map, "Write the map (key-frames, pose graph; docs/map-format.md) to this file at the end");
  replay_cmd->add_option("--load-map", replay.load_map, "Start in the map of this file: frames are LOST until one is found in it, poses then in its frame");
  replay_cmd->add_option("--vocabulary", replay.vocabulary, "Place-recognition vocabulary of the wide-angle camera, from `rankslam vocabulary` (default: the built-in one)");
  replay_cmd->add_flag("--no-wheels", replay.no_wheels, "Ignore the recording's can.log: vision only (the wheel odometry is otherwise the motion prior and the fallback)");

  SimulateArgs simulate;
  std::string scenes;
  for (const auto& name : rankslam::sim::scene_names()) scenes += "\n  " + name + ": " + rankslam::sim::scene_description(name);
  auto* simulate_cmd = app.add_subcommand("simulate", "Write a deterministic synthetic recording with exact ground truth. Scenes:" + scenes);
  simulate_cmd->add_option("scene", simulate.scene, "Scene name")->required()->check(CLI::IsMember(rankslam::sim::scene_names()));
  simulate_cmd->add_option("--out,-o", simulate.out, "Output recording directory (absent or empty)")->required();
  simulate_cmd->add_option("--frames,-n", simulate.frames, "Number of RGB-D frames (0 = the scene's default)")->check(CLI::NonNegativeNumber);
  simulate_cmd->add_option("--seed,-s", simulate.seed, "Random seed; equal seeds give byte-identical recordings");
  simulate_cmd->add_option("--scene-seed", simulate.scene_seed, "Seed of the textures alone (0: --seed): the same place, painted alike, under other noise");
  simulate_cmd->add_flag("--motion-blur", simulate.motion_blur, "Blur images by the camera motion during exposure");

  VocabularyArgs vocabulary;
  auto* vocabulary_cmd = app.add_subcommand("vocabulary", "Train a place-recognition vocabulary (k-means words of SIFT descriptors) from recordings' colour frames and wide-angle images");
  vocabulary_cmd->add_option("recordings", vocabulary.recordings, "Recording directories")->required();
  vocabulary_cmd->add_option("--out,-o", vocabulary.out, "Vocabulary file to write")->required();
  vocabulary_cmd->add_option("--words,-k", vocabulary.words, "Words (k-means centres)")->check(CLI::Range(1, 1024));
  vocabulary_cmd->add_option("--every", vocabulary.every, "Use every n-th colour frame and wide-angle image")->check(CLI::Range(1, 100000));
  vocabulary_cmd->add_option("--max-descriptors", vocabulary.max_descriptors, "Cluster at most this many descriptors, evenly spaced")->check(CLI::Range(1024, 10000000));
  vocabulary_cmd->add_option("--seed,-s", vocabulary.seed, "Seed of the k-means++ start");

  EvalArgs eval;
  auto* eval_cmd = app.add_subcommand("eval", "TUM absolute trajectory error and relative pose error of EST against GT");
  eval_cmd->add_option("ground_truth", eval.ground_truth, "Ground-truth trajectory (TUM format)")->required();
  eval_cmd->add_option("estimate", eval.estimate, "Estimated trajectory (TUM format)")->required();
  eval_cmd->add_option("--max-difference", eval.max_difference_s, "Largest stamp difference of associated poses, s")->check(CLI::PositiveNumber);
  eval_cmd->add_option("--delta", eval.delta_s, "RPE interval, s")->check(CLI::PositiveNumber);

  StereoVoArgs stereo;
  auto* stereo_cmd = app.add_subcommand("stereo-vo", "Stereo visual odometry over a EuRoC (ASL) or KITTI odometry sequence: trajectory, report and plot");
  stereo_cmd->add_option("dataset", stereo.dataset, "Sequence directory: EuRoC (DIR/mav0/cam0, cam1) or KITTI (DIR/image_0, image_1, calib.txt, times.txt)")->required();
  stereo_cmd->add_option("--out,-o", stereo.out, "Output directory")->required();
  stereo_cmd->add_option("--features", stereo.features, "Features: ros2d (default), sift or orb")->check(CLI::IsMember({"ros2d", "sift", "orb"}));
  stereo_cmd->add_flag("--no-ba", stereo.no_ba, "Frame-to-frame odometry only, without the sliding-window bundle adjustment");
  stereo_cmd->add_option("--max-frames", stereo.max_frames, "Process at most this many stereo pairs (0 = all)")->check(CLI::NonNegativeNumber);
  stereo_cmd->add_option("--seed", stereo.seed, "Seed of the MSSE hypothesis sampler (0 = the built-in seed), to measure the spread over samplings")->check(CLI::NonNegativeNumber);
  stereo_cmd->add_option("--ground-truth", stereo.ground_truth, "Ground truth of the left camera (TUM format, or KITTI poses), instead of the dataset's own");

  RunArgs run;
  auto* run_cmd = app.add_subcommand("run", "Run live on the robot: sensors in, pose out over CAN");
  run_cmd->add_option("--config,-c", run.config, "Robot configuration (deploy/config/<robot>.yaml)")->required();
  run_cmd->add_option("--out,-o", run.out, "Where trajectory and map are flushed on exit");
  run_cmd->add_option("--mode,-m", run.mode, "Registration: baseline, photometric, geometric or fused (default: fused)");
  run_cmd->add_option("--frame", run.frame, "Frame of trajectory.txt and map.ply: base (default: the map frame of the base, x forward, z up) or camera (the first camera's optical frame)")
      ->check(CLI::IsMember({"camera", "base"}));
  run_cmd->add_option("--load-map", run.load_map, "Start in the map of this file: LOST until the camera is found in it, poses then in its frame (default: map.file when it exists)");
  run_cmd->add_option("--vocabulary", run.vocabulary, "Place-recognition vocabulary of the wide-angle camera, from `rankslam vocabulary` (default: the built-in one)");
  run_cmd->add_option("--save-map", run.save_map, "Write the map to this file at every checkpoint and at exit (default: map.file)");
  run_cmd->add_option("--can-interface", run.can_interface, "SocketCAN interface, instead of the configuration's can.interface (said when they differ)")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            return text.empty() || text.size() >= 16 ? "--can-interface must be a network interface name of 1 .. 15 characters" : "";
          },
          "IFACE"));

  RecordArgs record;
  auto* record_cmd = app.add_subcommand("record", "Record the live sensors (camera, CAN) into a recording directory (TUM layout, see README)");
  record_cmd->add_option("--out,-o", record.out, "Output recording directory (absent or empty)")->required();
  record_cmd->add_option("--config,-c", record.config, "Robot configuration naming camera and CAN interface (default: first OpenNI2 device, no CAN)");
  record_cmd->add_option("--frames,-n", record.frames, "Stop after this many frames (0 = until stopped)");
  record_cmd->add_option("--seconds,-s", record.seconds, "Stop after this many seconds (0 = until stopped)")->check(CLI::NonNegativeNumber);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    (void)app.exit(e);
    return kExitUsage;
  }

  try {
    if (replay_cmd->parsed()) return run_replay(replay);
    if (simulate_cmd->parsed()) return run_simulate(simulate);
    if (vocabulary_cmd->parsed()) return run_vocabulary(vocabulary);
    if (eval_cmd->parsed()) return run_eval(eval);
    if (run_cmd->parsed()) return run_live(run);
    if (stereo_cmd->parsed()) return run_stereo_vo(stereo);
    if (record_cmd->parsed()) return run_record(record);
  } catch (const std::exception& error) {
    std::cerr << "internal error: " << error.what() << "\n";
    return kExitInternal;
  }
  return kExitUsage;
}
