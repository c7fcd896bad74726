// Wheel-only odometry on the simulated corridor loop: the base pose from can.log, carried to the
// colour camera with the recording's T_base_cam, against groundtruth.txt (TUM ATE), and the
// listed wheel-slip segments against the ground truth's motion.
//
// The whole loop (about 93 s, 2800 camera frames) is simulated without images: with them it
// would be 2.6 GB of PNGs that the odometry never reads, so its can.log is parsed with the
// replay's candump parser and its calibration with the replay's YAML reader. A short stretch
// with images goes through replay::open_recording end to end and must agree with it.
#include "rankslam/eval/metrics.hpp"
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/hal/candump.hpp"
#include "rankslam/nav/wheel_odometry.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/sim/simulator.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

namespace rankslam::nav {
namespace {

namespace fs = std::filesystem;

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("rankslam_bench_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  return dir;
}

struct Slip {
  double start_s = 0.0;
  double end_s = 0.0;
  std::string wheel;
};

// A simulated recording as the odometry needs it.
struct WheelRecording {
  std::string error;
  hal::Calibration calibration;
  std::vector<hal::CanFrame> can_frames;
  eval::Trajectory ground_truth;  // colour camera in the world, 30 Hz
  std::vector<Slip> slips;
};

std::string read_slips(const fs::path& path, std::vector<Slip>& slips) {
  std::ifstream in(path);
  if (!in) return "cannot open " + path.string();
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    Slip slip;
    if (!(fields >> slip.start_s >> slip.end_s >> slip.wheel)) {
      return path.string() + ":" + std::to_string(line_number) + ": expected 'start_stamp end_stamp wheel'";
    }
    slips.push_back(slip);
  }
  return {};
}

// Recording without images: calibration.yaml, can.log, groundtruth.txt, slip.txt.
WheelRecording load_without_images(const fs::path& dir) {
  WheelRecording r;
  if (auto error = replay::load_calibration_yaml(dir / "calibration.yaml", r.calibration); !error.empty()) {
    r.error = error;
    return r;
  }
  std::ifstream can_log(dir / "can.log");
  if (!can_log) {
    r.error = "cannot open " + (dir / "can.log").string();
    return r;
  }
  std::string line;
  int line_number = 0;
  while (std::getline(can_log, line)) {
    ++line_number;
    if (line.empty() || line[0] == '#') continue;
    const auto frame = hal::parse_candump_line(line);
    if (!frame) {
      r.error = (dir / "can.log").string() + ":" + std::to_string(line_number) + ": not a candump -l frame";
      return r;
    }
    r.can_frames.push_back(*frame);
  }
  auto ground_truth = eval::read_tum_trajectory(dir / "groundtruth.txt");
  if (!ground_truth) {
    r.error = ground_truth.error();
    return r;
  }
  r.ground_truth = std::move(ground_truth.value());
  if (fs::exists(dir / "slip.txt")) r.error = read_slips(dir / "slip.txt", r.slips);
  return r;
}

struct OdometryRun {
  std::unique_ptr<WheelOdometry> odometry;
  eval::Trajectory estimate;  // colour camera in the odometry frame, at the ground-truth stamps
  double ate_m = 0.0;
  double end_position_error_m = 0.0;
  double end_yaw_error_rad = 0.0;
  double path_length_m = 0.0;
};

// Recording stamps have microseconds; a double near 1.7e9 s resolves 0.24 µs, so rounding to
// the microsecond recovers the CAN frames' exact nanosecond stamps.
std::int64_t to_ns(double stamp_s) { return std::llround(stamp_s * 1e6) * 1000; }

double yaw_of(const Eigen::Isometry3d& T) { return std::atan2(T(1, 0), T(0, 0)); }

// Runs the odometry over every CAN frame, then samples the base pose at the camera stamps.
OdometryRun run_odometry(const WheelRecording& r) {
  OdometryRun run;
  EXPECT_TRUE(r.calibration.wheels.has_value());
  const hal::WheelGeometry wheels = r.calibration.wheels.value_or(hal::WheelGeometry{});
  WheelOdometryConfig config;
  config.history_capacity = static_cast<int>(r.can_frames.size()) + 1;  // the whole run, for the evaluation
  EXPECT_EQ(validate(config, wheels), "");
  run.odometry = std::make_unique<WheelOdometry>(config, wheels);
  for (const auto& frame : r.can_frames) {
    const WheelFrameResult result = run.odometry->update(frame);
    EXPECT_TRUE(result == WheelFrameResult::kIntegrated || result == WheelFrameResult::kBaseline)
        << to_string(result) << " at " << frame.stamp_ns;
  }
  const Eigen::Isometry3d& T_base_cam = r.calibration.rgb.T_base_cam;
  // Camera frames inside the wheel stream (the last one may follow the last wheel frame).
  std::size_t first_index = r.ground_truth.size();
  std::size_t last_index = 0;
  for (std::size_t i = 0; i < r.ground_truth.size(); ++i) {
    Pose2d T_odom_base;
    if (!run.odometry->pose_at(to_ns(r.ground_truth[i].stamp_s), T_odom_base)) continue;
    run.estimate.push_back({r.ground_truth[i].stamp_s, to_isometry3d(T_odom_base) * T_base_cam});
    first_index = std::min(first_index, i);
    last_index = i;
  }
  if (run.estimate.empty()) return run;
  EXPECT_GT(run.estimate.size(), 0.95 * static_cast<double>(r.ground_truth.size()));
  auto ate = eval::compute_ate(r.ground_truth, run.estimate);
  EXPECT_TRUE(static_cast<bool>(ate)) << (ate ? std::string() : ate.error());
  if (!ate) return run;
  run.ate_m = ate.value().translation_m.rmse;

  // End point: the base's motion from the first to the last common stamp, odometry against
  // ground truth, in the base frame at the start.
  const Eigen::Isometry3d cam_base = T_base_cam.inverse();
  const Eigen::Isometry3d gt_motion = (r.ground_truth[first_index].T_world_cam * cam_base).inverse() *
                                      (r.ground_truth[last_index].T_world_cam * cam_base);
  Pose2d first;
  Pose2d last;
  EXPECT_TRUE(run.odometry->pose_at(to_ns(r.ground_truth[first_index].stamp_s), first));
  EXPECT_TRUE(run.odometry->pose_at(to_ns(r.ground_truth[last_index].stamp_s), last));
  const Pose2d wheel_motion = compose(inverse(first), last);
  run.end_position_error_m = std::hypot(wheel_motion.x_m - gt_motion.translation().x(),
                                        wheel_motion.y_m - gt_motion.translation().y());
  run.end_yaw_error_rad = std::abs(wrap_angle(wheel_motion.yaw_rad - yaw_of(gt_motion)));
  for (std::size_t i = 1; i < r.ground_truth.size(); ++i) {
    run.path_length_m += (r.ground_truth[i].T_world_cam.translation() - r.ground_truth[i - 1].T_world_cam.translation()).norm();
  }
  return run;
}

// One whole loop (the scene's default length) without images.
WheelRecording simulate_loop(std::uint64_t seed, bool slip) {
  const fs::path dir = fresh_dir("corridor_wheels_" + std::to_string(seed) + (slip ? "_slip" : "_noslip"));
  sim::SimulationOptions options;
  options.scene = "corridor-loop";
  options.out_dir = dir;
  options.seed = seed;
  options.images = false;
  options.wheel_slip = slip;
  WheelRecording recording;
  recording.error = sim::simulate_recording(options, nullptr);
  if (recording.error.empty()) recording = load_without_images(dir);
  fs::remove_all(dir);
  return recording;
}

// Seed 1's loop, once with the simulator's wheel slip and once without.
class CorridorLoopWheels : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    with_slip_ = new WheelRecording(simulate_loop(1, true));
    without_slip_ = new WheelRecording(simulate_loop(1, false));
  }
  static void TearDownTestSuite() {
    delete with_slip_;
    delete without_slip_;
  }
  static WheelRecording* with_slip_;
  static WheelRecording* without_slip_;
};

WheelRecording* CorridorLoopWheels::with_slip_ = nullptr;
WheelRecording* CorridorLoopWheels::without_slip_ = nullptr;

TEST_F(CorridorLoopWheels, WheelOnlyTrajectoryAgainstGroundTruth) {
  ASSERT_TRUE(with_slip_->error.empty()) << with_slip_->error;
  ASSERT_TRUE(without_slip_->error.empty()) << without_slip_->error;
  const OdometryRun slipping = run_odometry(*with_slip_);
  const OdometryRun clean = run_odometry(*without_slip_);
  const WheelOdometryState& state = slipping.odometry->state();
  std::printf("corridor-loop wheel odometry, %zu CAN frames, %.2f m driven (ground truth %.2f m of camera path), "
              "%zu slips listed\n",
              with_slip_->can_frames.size(), state.distance_m, slipping.path_length_m, with_slip_->slips.size());
  std::printf("  with slip:    ATE %.5f m, end point %.5f m / %.3f deg; final sigma x %.4f m, y %.4f m, yaw %.2f deg\n",
              slipping.ate_m, slipping.end_position_error_m, slipping.end_yaw_error_rad * 180.0 / std::numbers::pi,
              std::sqrt(state.covariance(0, 0)), std::sqrt(state.covariance(1, 1)),
              std::sqrt(state.covariance(2, 2)) * 180.0 / std::numbers::pi);
  std::printf("  without slip: ATE %.5f m, end point %.5f m / %.3f deg\n", clean.ate_m, clean.end_position_error_m,
              clean.end_yaw_error_rad * 180.0 / std::numbers::pi);

  // Every frame of the clean stream integrates; the counters wrap within the first metres.
  const WheelOdometryStats& stats = slipping.odometry->stats();
  EXPECT_EQ(stats.frames_received, with_slip_->can_frames.size());
  EXPECT_EQ(stats.frames_integrated + 1, stats.frames_received);
  EXPECT_EQ(stats.gaps + stats.duplicates + stats.out_of_order + stats.implausible + stats.timestamp_jumps_backward +
                stats.timestamp_jumps_forward + stats.counter_rebases + stats.encoder_faults + stats.malformed,
            0U);

  // Bounds: the figures measured for seed 1 (ATE 0.157 m, end point 0.562 m / 5.6 deg with
  // slip; 0.03 mm and 0.02 mm without) with a margin. Without slip only tick quantisation
  // and read jitter remain, which absolute counters do not accumulate.
  EXPECT_LE(clean.ate_m, 0.0005);
  EXPECT_LE(clean.end_position_error_m, 0.0005);
  EXPECT_LE(clean.end_yaw_error_rad, 0.1 * std::numbers::pi / 180.0);
  EXPECT_LE(slipping.ate_m, 0.20);
  EXPECT_LE(slipping.end_position_error_m, 0.70);
  // Slip is what separates the two runs.
  EXPECT_GT(slipping.ate_m, 100.0 * clean.ate_m);
  EXPECT_GT(slipping.end_yaw_error_rad, 2.0 * std::numbers::pi / 180.0);
}

struct SlipCheck {
  int slips = 0;
  double smallest_slip_rad = 1e9;  // yaw discrepancy over the least visible slip
  double largest_clean_rad = 0.0;  // over the worst slip-free window
  int clean_windows = 0;
};

// Yaw change of the wheels against the ground truth's, over each listed slip (between the
// camera frames enclosing it) and over every 0.5 s window clear of slips (by 0.1 s).
SlipCheck check_slips(const WheelRecording& r) {
  SlipCheck check;
  const OdometryRun run = run_odometry(r);
  const Eigen::Isometry3d cam_base = r.calibration.rgb.T_base_cam.inverse();
  const auto yaw_discrepancy = [&](std::size_t i, std::size_t j, double& value) {
    RelativeMotion motion;
    if (run.odometry->relative_motion(to_ns(r.ground_truth[i].stamp_s), to_ns(r.ground_truth[j].stamp_s), motion) !=
        RelativeMotionStatus::kOk) {
      return false;
    }
    const Eigen::Isometry3d gt =
        (r.ground_truth[i].T_world_cam * cam_base).inverse() * (r.ground_truth[j].T_world_cam * cam_base);
    value = wrap_angle(motion.T_a_b.yaw_rad - yaw_of(gt));  // signed: wheels turned more to the left
    return true;
  };
  const auto stamp = [&](std::size_t i) { return r.ground_truth[i].stamp_s; };
  std::printf("  wheel-only ATE %.4f m\n", run.ate_m);
  for (const Slip& slip : r.slips) {
    std::size_t i = 0;
    while (i + 1 < r.ground_truth.size() && stamp(i + 1) <= slip.start_s) ++i;
    std::size_t j = i;
    while (j + 1 < r.ground_truth.size() && stamp(j) < slip.end_s) ++j;
    double discrepancy = 0.0;
    EXPECT_TRUE(yaw_discrepancy(i, j, discrepancy)) << "slip at " << slip.start_s;
    std::printf("  slip %6.2f .. %6.2f s (%s wheel): wheel yaw off ground truth by %+.2f deg\n", slip.start_s - stamp(0),
                slip.end_s - stamp(0), slip.wheel.c_str(), discrepancy * 180.0 / std::numbers::pi);
    // An over-counting right wheel turns the odometry left (positive yaw), a left one right.
    EXPECT_EQ(discrepancy > 0.0, slip.wheel == "right") << "slip at " << slip.start_s;
    check.smallest_slip_rad = std::min(check.smallest_slip_rad, std::abs(discrepancy));
    ++check.slips;
  }
  for (std::size_t i = 0; i + 15 < r.ground_truth.size(); i += 3) {
    const std::size_t j = i + 15;
    const bool clear = std::none_of(r.slips.begin(), r.slips.end(), [&](const Slip& slip) {
      return slip.start_s < stamp(j) + 0.1 && slip.end_s > stamp(i) - 0.1;
    });
    double discrepancy = 0.0;
    if (!clear || !yaw_discrepancy(i, j, discrepancy)) continue;
    check.largest_clean_rad = std::max(check.largest_clean_rad, std::abs(discrepancy));
    ++check.clean_windows;
  }
  return check;
}

TEST_F(CorridorLoopWheels, SlipSegmentsShowAsYawDiscrepancy) {
  // Seed 1 and three more loops, for more slips of either wheel.
  for (std::uint64_t seed = 1; seed <= 4; ++seed) {
    const WheelRecording other = seed == 1 ? WheelRecording{} : simulate_loop(seed, true);
    const WheelRecording& r = seed == 1 ? *with_slip_ : other;
    ASSERT_TRUE(r.error.empty()) << r.error;
    ASSERT_FALSE(r.slips.empty());
    std::printf("seed %d:\n", static_cast<int>(seed));
    const SlipCheck check = check_slips(r);
    std::printf("  slip-free 0.5 s windows: %d, largest yaw discrepancy %.3f deg; smallest over a slip %.2f deg\n",
                check.clean_windows, check.largest_clean_rad * 180.0 / std::numbers::pi,
                check.smallest_slip_rad * 180.0 / std::numbers::pi);
    EXPECT_EQ(check.slips, static_cast<int>(r.slips.size()));
    EXPECT_GT(check.clean_windows, 400);
    // Every listed slip stands out: above an absolute 0.5 deg and ten times the clean maximum.
    EXPECT_GT(check.smallest_slip_rad, 0.5 * std::numbers::pi / 180.0) << "seed " << seed;
    EXPECT_GT(check.smallest_slip_rad, 10.0 * check.largest_clean_rad) << "seed " << seed;
  }
}

// A short stretch with images, end to end through replay::open_recording: the CAN frames the
// replay indexes drive the odometry to the same poses as the image-less loop's first seconds.
TEST_F(CorridorLoopWheels, ReplayRecordingGivesTheSameOdometry) {
  ASSERT_TRUE(with_slip_->error.empty()) << with_slip_->error;
  const fs::path dir = fresh_dir("corridor_wheels_replay");
  sim::SimulationOptions options;
  options.scene = "corridor-loop";
  options.out_dir = dir;
  options.seed = 1;
  options.frames = 90;  // 3 s
  ASSERT_EQ(sim::simulate_recording(options, nullptr), "");
  replay::Recording recording;
  const std::string error = replay::open_recording(dir, recording);
  fs::remove_all(dir);
  ASSERT_EQ(error, "");
  ASSERT_TRUE(recording.calibration.wheels.has_value());
  ASSERT_EQ(recording.can_frames.size(), 297U);  // 89/30 s at 100 Hz: frames 0 .. 296

  WheelOdometryConfig config;
  WheelOdometry replayed(config, *recording.calibration.wheels);
  for (const auto& frame : recording.can_frames) {
    const WheelFrameResult result = replayed.update(frame);
    ASSERT_TRUE(result == WheelFrameResult::kIntegrated || result == WheelFrameResult::kBaseline) << to_string(result);
  }
  const OdometryRun loop = run_odometry(*with_slip_);
  Pose2d from_loop;
  ASSERT_TRUE(loop.odometry->pose_at(replayed.state().stamp_ns, from_loop));
  EXPECT_EQ(replayed.state().T_odom_base.x_m, from_loop.x_m);
  EXPECT_EQ(replayed.state().T_odom_base.y_m, from_loop.y_m);
  EXPECT_EQ(replayed.state().T_odom_base.yaw_rad, from_loop.yaw_rad);
  std::printf("  replayed 3 s stretch: base at (%.4f, %.4f) m, yaw %.3f deg, %.3f m driven\n",
              replayed.state().T_odom_base.x_m, replayed.state().T_odom_base.y_m,
              replayed.state().T_odom_base.yaw_rad * 180.0 / std::numbers::pi, replayed.state().distance_m);
}

}  // namespace
}  // namespace rankslam::nav
