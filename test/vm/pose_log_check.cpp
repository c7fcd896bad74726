// Checks the CAN log of a `rankslam run` against the trajectory `rankslam replay` wrote for the
// same recording: every pose cycle (odom pose composed with the map-odom frames) decodes to the
// replayed pose of the frame it names, moved on by the wheel odometry since that frame, within
// 1 mm and 0.1°, cycles and heartbeats arrive at
// their configured rates, the watchdog reports LOST once the camera stops while heartbeats go on,
// the run took its wheel prior from the frames received on the bus, and it flushed its outputs.
//
//   pose_log_check --log CANDUMP_L --reference TRAJ --recording DIR --run-out DIR
//                  --pose-rate HZ --heartbeat-rate HZ --watchdog-s S [--faults FROM_S TO_S]
//
// --faults: the bus failed between these CLOCK_REALTIME times (candump's stamps). Lost or
// broken cycles and counter jumps are allowed there only; the run must have counted frames it
// could not send, flagged them in a heartbeat, and kept its rates before and after.
#include "rankslam/eval/trajectory.hpp"
#include "rankslam/hal/candump.hpp"
#include "rankslam/nav/pose_frames.hpp"
#include "rankslam/nav/wheel_odometry.hpp"
#include "rankslam/replay/recording.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <regex>
#include <sstream>
#include <set>
#include <string>
#include <vector>

namespace {

using namespace rankslam;

struct Cycle {
  std::int64_t stamp_ns = 0;
  nav::PoseXYYaw xy_yaw;
  nav::PoseZRollPitch z_roll_pitch;
  nav::PoseXYYaw map_odom_xy_yaw;
  nav::PoseZRollPitch map_odom_z_roll_pitch;
  nav::PoseVelocity velocity;
  nav::PoseQuality quality;
  /// The newest wheel frame on the bus before the cycle, as an index into the recording's CAN
  /// frames (-1: none yet).
  long newest_wheel = -1;
};

int g_failures = 0;

void fail(const std::string& message) {
  std::printf("FAIL: %s\n", message.c_str());
  ++g_failures;
}

double rotation_angle_deg(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle() * 180.0 / std::numbers::pi;
}

double yaw_difference_deg(double a, double b) { return std::abs(std::fmod(a - b + 540.0, 360.0) - 180.0); }

// An integer field of a report.json; -1 when the file or the field is missing.
long report_integer(const std::filesystem::path& path, const std::string& key) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  const std::string report = text.str();
  std::smatch match;
  if (!std::regex_search(report, match, std::regex("\"" + key + "\": (-?\\d+)"))) return -1;
  return std::stol(match[1]);
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> arg;
  for (int i = 1; i + 1 < argc; i += 2) arg[argv[i]] = argv[i + 1];
  for (const char* key : {"--log", "--reference", "--recording", "--run-out", "--pose-rate", "--heartbeat-rate", "--watchdog-s"}) {
    if (!arg.contains(key)) {
      std::fprintf(stderr, "usage: %s --log F --reference F --recording D --run-out D --pose-rate HZ --heartbeat-rate HZ --watchdog-s S (missing %s)\n", argv[0], key);
      return 2;
    }
  }
  const double pose_rate_hz = std::stod(arg["--pose-rate"]);
  const double heartbeat_rate_hz = std::stod(arg["--heartbeat-rate"]);
  const double watchdog_s = std::stod(arg["--watchdog-s"]);
  // The fault window; empty without --faults.
  std::int64_t faults_from_ns = 0;
  std::int64_t faults_to_ns = -1;
  for (int i = 1; i + 2 < argc; ++i) {
    if (std::string(argv[i]) == "--faults") {
      faults_from_ns = std::llround(std::stod(argv[i + 1]) * 1e9);
      faults_to_ns = std::llround(std::stod(argv[i + 2]) * 1e9);
    }
  }
  const bool faults = faults_to_ns >= faults_from_ns;
  // Whether [a, b] overlaps the fault window.
  const auto touches_faults = [&](std::int64_t a_ns, std::int64_t b_ns) { return faults && b_ns >= faults_from_ns && a_ns <= faults_to_ns; };

  replay::Recording recording;
  if (auto error = replay::open_recording(arg["--recording"], recording); !error.empty()) {
    std::printf("FAIL: %s\n", error.c_str());
    return 1;
  }
  const Eigen::Isometry3d T_base_cam = recording.calibration.rgb.T_base_cam;
  auto reference = eval::read_tum_trajectory(arg["--reference"]);
  if (!reference) {
    std::printf("FAIL: %s\n", reference.error().c_str());
    return 1;
  }

  // Parse the log into pose cycles and heartbeats.
  std::ifstream log(arg["--log"]);
  if (!log) {
    std::printf("FAIL: cannot open %s\n", arg["--log"].c_str());
    return 1;
  }
  std::vector<Cycle> cycles;
  std::vector<std::pair<std::int64_t, nav::Heartbeat>> heartbeats;
  // The played wheel frames on the bus, matched in order to the recording's (by identifier and
  // data), as `run` matches the ones it receives.
  const std::vector<hal::CanFrame>& recorded = recording.can_frames;
  std::size_t next_recorded = 0;
  long newest_wheel = -1;
  const std::uint32_t wheel_id = recording.calibration.wheels.value_or(hal::WheelGeometry{}).can_id;
  std::optional<Cycle> partial;
  int stage = 0;
  int broken_cycles = 0;
  int broken_in_faults = 0;
  // A cycle broken off at `stamp_ns`: allowed only when it overlaps the fault window.
  const auto broken = [&](std::int64_t stamp_ns) {
    ++(touches_faults(partial ? partial->stamp_ns : stamp_ns, stamp_ns) ? broken_in_faults : broken_cycles);
  };
  long output_frames = 0;  // pose and heartbeat frames: what the run's own socket sent
  long capture_drops = 0;
  std::string line;
  const std::regex drop_line(R"(^DROPCOUNT: .*\(total drops (\d+)\))");
  while (std::getline(log, line)) {
    std::smatch drop;
    if (std::regex_search(line, drop, drop_line)) capture_drops = std::max(capture_drops, std::stol(drop[1]));
    const auto frame = hal::parse_candump_line(line);
    if (!frame) continue;
    if (frame->id != wheel_id) ++output_frames;
    if (frame->id == wheel_id) {
      for (std::size_t i = next_recorded; i < recorded.size() && i < next_recorded + 16; ++i) {
        if (recorded[i].id == frame->id && recorded[i].data == frame->data) {
          newest_wheel = static_cast<long>(i);
          next_recorded = i + 1;
          break;
        }
      }
    } else if (frame->id == nav::kPoseXYYawId) {
      if (stage != 0) broken(frame->stamp_ns);
      partial = Cycle{};
      partial->stamp_ns = frame->stamp_ns;
      partial->newest_wheel = newest_wheel;
      const auto decoded = nav::decode_pose_xy_yaw(*frame);
      if (!decoded) { fail("undecodable PoseXYYaw: " + line); stage = 0; continue; }
      partial->xy_yaw = *decoded;
      stage = 1;
    } else if (frame->id == nav::kPoseZRollPitchId) {
      const auto decoded = nav::decode_pose_z_roll_pitch(*frame);
      if (stage != 1 || !decoded || decoded->counter != partial->xy_yaw.counter) { broken(frame->stamp_ns); stage = 0; continue; }
      partial->z_roll_pitch = *decoded;
      stage = 2;
    } else if (frame->id == nav::kMapOdomXYYawId) {
      const auto decoded = nav::decode_pose_xy_yaw(*frame, nav::kMapOdomXYYawId);
      if (stage != 2 || !decoded || decoded->counter != partial->xy_yaw.counter) { broken(frame->stamp_ns); stage = 0; continue; }
      partial->map_odom_xy_yaw = *decoded;
      stage = 3;
    } else if (frame->id == nav::kMapOdomZRollPitchId) {
      const auto decoded = nav::decode_pose_z_roll_pitch(*frame, nav::kMapOdomZRollPitchId);
      if (stage != 3 || !decoded || decoded->counter != partial->xy_yaw.counter) { broken(frame->stamp_ns); stage = 0; continue; }
      partial->map_odom_z_roll_pitch = *decoded;
      stage = 4;
    } else if (frame->id == nav::kPoseVelocityId) {
      const auto decoded = nav::decode_pose_velocity(*frame);
      if (stage != 4 || !decoded || decoded->counter != partial->xy_yaw.counter) { broken(frame->stamp_ns); stage = 0; continue; }
      partial->velocity = *decoded;
      stage = 5;
    } else if (frame->id == nav::kPoseQualityId) {
      const auto decoded = nav::decode_pose_quality(*frame);
      if (stage != 5 || !decoded || decoded->counter != partial->xy_yaw.counter) { broken(frame->stamp_ns); stage = 0; continue; }
      partial->quality = *decoded;
      cycles.push_back(*partial);
      stage = 0;
    } else if (frame->id == nav::kHeartbeatId) {
      const auto decoded = nav::decode_heartbeat(*frame);
      if (!decoded) { fail("undecodable Heartbeat: " + line); continue; }
      heartbeats.emplace_back(frame->stamp_ns, *decoded);
    }
  }
  // The capture first: frames its socket dropped say nothing about what rankslam sent.
  const std::filesystem::path run_report = std::filesystem::path(arg["--run-out"]) / "report.json";
  const long sent = report_integer(run_report, "bus_frames_tx");
  const long tx_dropped = report_integer(run_report, "tx_dropped");
  const long tx_faults = report_integer(run_report, "tx_faults");
  std::printf("frames rankslam sent %ld (refused: queue full %ld, bus down %ld), captured %ld; capture drops %ld\n", sent,
              tx_dropped, tx_faults, output_frames, capture_drops);
  if (capture_drops > 0) fail("candump's socket dropped " + std::to_string(capture_drops) + " frames: the capture, not the run, lost them");
  if (!faults) {
    if (sent != output_frames) fail("the run reports " + std::to_string(sent) + " frames sent, the bus carried " + std::to_string(output_frames));
    if (tx_dropped != 0 || tx_faults != 0) fail("the run could not send every frame");
  } else {
    // Frames netem still held when its queue was removed count as sent but never reach the bus.
    if (sent < output_frames) fail("the bus carried more frames than the run reports sent");
    if (tx_dropped <= 0) fail("no frame counted as refused by the full transmit queue (tx_dropped)");
    if (tx_faults <= 0) fail("no frame counted as not sent on the downed interface (tx_faults)");
    std::printf("pose cycles broken by the faults: %d\n", broken_in_faults);
  }
  if (broken_cycles > 0) fail(std::to_string(broken_cycles) + " incomplete or interleaved pose cycles");
  if (cycles.size() < 10) {
    fail("only " + std::to_string(cycles.size()) + " pose cycles in the log");
    return 1;
  }
  for (std::size_t i = 1; i < cycles.size(); ++i) {
    if (cycles[i].xy_yaw.counter != (cycles[i - 1].xy_yaw.counter + 1) % nav::kPoseCounterModulus &&
        !touches_faults(cycles[i - 1].stamp_ns, cycles[i].stamp_ns)) {
      fail("pose cycle counter jumps at cycle " + std::to_string(i));
      break;
    }
  }
  std::int64_t largest_gap_ns = 0;
  for (std::size_t i = 1; i < cycles.size(); ++i) {
    if (!touches_faults(cycles[i - 1].stamp_ns, cycles[i].stamp_ns)) largest_gap_ns = std::max(largest_gap_ns, cycles[i].stamp_ns - cycles[i - 1].stamp_ns);
  }
  std::printf("largest gap between pose cycles %.1f ms (period %.1f ms)\n", static_cast<double>(largest_gap_ns) * 1e-6, 1e3 / pose_rate_hz);

  // Rates, from the kernel receive stamps of the capturing socket; with faults, before and after them.
  const auto check_rate = [&](const char* what, const std::vector<std::int64_t>& all_stamps, double configured_hz) {
    for (const bool after : {false, true}) {
      std::vector<std::int64_t> stamps;
      for (const std::int64_t stamp : all_stamps) {
        if (!faults || (after ? stamp > faults_to_ns : stamp < faults_from_ns)) stamps.push_back(stamp);
      }
      if (stamps.size() < 2) {
        fail(std::string("fewer than two ") + what + (faults ? (after ? " after the faults" : " before the faults") : ""));
      } else {
        const double span_s = static_cast<double>(stamps.back() - stamps.front()) * 1e-9;
        const double hz = static_cast<double>(stamps.size() - 1) / span_s;
        std::printf("%s%s: %zu over %.2f s, %.2f Hz (configured %.1f Hz)\n", what,
                    faults ? (after ? " after the faults" : " before the faults") : "", stamps.size(), span_s, hz, configured_hz);
        if (std::abs(hz - configured_hz) > 0.1 * configured_hz) fail(std::string(what) + " rate is not within 10 % of the configured rate");
      }
      if (!faults) break;
    }
  };
  std::vector<std::int64_t> cycle_stamps;
  for (const Cycle& cycle : cycles) cycle_stamps.push_back(cycle.stamp_ns);
  check_rate("pose cycles", cycle_stamps, pose_rate_hz);
  std::vector<std::int64_t> heartbeat_stamps;
  for (const auto& [stamp_ns, heartbeat] : heartbeats) heartbeat_stamps.push_back(stamp_ns);
  check_rate("heartbeats", heartbeat_stamps, heartbeat_rate_hz);
  for (std::size_t i = 1; i < heartbeats.size(); ++i) {
    if (heartbeats[i].second.counter != static_cast<std::uint8_t>(heartbeats[i - 1].second.counter + 1U) &&
        !touches_faults(heartbeats[i - 1].first, heartbeats[i].first)) {
      fail("heartbeat rolling counter jumps at heartbeat " + std::to_string(i));
      break;
    }
  }
  if (faults) {
    // The first heartbeat that gets through after refused frames says so (CanTxDropped).
    bool flagged = false;
    for (const auto& [stamp_ns, heartbeat] : heartbeats) flagged = flagged || (heartbeat.can_tx_dropped && stamp_ns >= faults_from_ns);
    if (!flagged) fail("no heartbeat flagged CanTxDropped after the faults");
  }

  // Poses against the replayed trajectory, frame by frame.
  const auto& ref = reference.value();
  if (ref.size() > 256) fail("the reference has more than 256 frames; the 8-bit frame counter is ambiguous");
  // A reference that never leaves the origin would let a broken encoder pass.
  double reach_m = 0.0;
  for (const auto& pose : ref) reach_m = std::max(reach_m, pose.T_world_cam.translation().norm());
  std::printf("reference: %zu frames, farthest %.3f m from the start\n", ref.size(), reach_m);
  if (reach_m < 0.01) fail("the reference trajectory moves less than 1 cm (10 position steps); the comparison would prove nothing");
  // Between camera frames `run` moves the pose on by the wheel odometry since the frame: the
  // expected pose is the replayed one moved by the wheels from the frame's stamp to one of the
  // wheel frames around the newest on the bus before the cycle (the two sockets receive in
  // their own time), or unmoved while the wheels have not passed the frame.
  if (!recording.calibration.wheels) fail("the recording has no wheels section");
  nav::WheelOdometryConfig wheel_config;
  wheel_config.history_capacity = static_cast<int>(recorded.size()) + 2;
  nav::WheelOdometry odometry(wheel_config, recording.calibration.wheels.value_or(hal::WheelGeometry{}));
  for (const hal::CanFrame& frame : recorded) (void)odometry.update(frame);
  const auto wheel_motion = [&](std::int64_t from_ns, std::int64_t to_ns, Eigen::Isometry3d& T) {
    nav::RelativeMotion motion;
    if (odometry.relative_motion(from_ns, to_ns, motion) != nav::RelativeMotionStatus::kOk) return false;
    T = nav::to_isometry3d(motion.T_a_b);
    return true;
  };
  int propagated_cycles = 0;
  double largest_propagation_m = 0.0;
  double max_position_m = 0.0;
  double max_rotation_deg = 0.0;
  double max_yaw_deg = 0.0;
  std::set<std::uint8_t> frames_seen;
  std::size_t compared = 0;
  // The uncertainty and the velocity: unknown where there is no estimate, sent where there is.
  int sigma_cycles = 0;
  int velocity_cycles = 0;
  for (const Cycle& cycle : cycles) {
    const nav::PoseStatus status = cycle.quality.status;
    const bool sigmas = cycle.quality.position_sigma_m && cycle.quality.yaw_sigma_deg;
    const bool velocity = cycle.velocity.vx_mps && cycle.velocity.vy_mps && cycle.velocity.yaw_rate_dps;
    if ((status == nav::PoseStatus::kInitialising || status == nav::PoseStatus::kLost) && (sigmas || velocity)) {
      fail("a pose cycle INITIALISING or LOST carries sigmas or a velocity");
      break;
    }
    if (status == nav::PoseStatus::kTracking && !sigmas) {
      fail("a TRACKING pose cycle carries unknown sigmas");
      break;
    }
    if (velocity && (std::hypot(*cycle.velocity.vx_mps, *cycle.velocity.vy_mps) > 5.0 ||
                     std::abs(*cycle.velocity.yaw_rate_dps) > 360.0)) {
      fail("implausible velocity in a pose cycle");
      break;
    }
    sigma_cycles += sigmas ? 1 : 0;
    velocity_cycles += velocity ? 1 : 0;
  }
  std::printf("pose cycles with sigmas %d, with a velocity %d, of %zu\n", sigma_cycles, velocity_cycles, cycles.size());
  if (velocity_cycles == 0) fail("no pose cycle carries a velocity");
  for (const Cycle& cycle : cycles) {
    if (cycle.quality.status == nav::PoseStatus::kInitialising) continue;
    const std::size_t index = cycle.quality.frame_counter;
    if (index >= ref.size()) {
      fail("pose cycle names frame " + std::to_string(index) + ", beyond the reference's " + std::to_string(ref.size()));
      continue;
    }
    frames_seen.insert(cycle.quality.frame_counter);
    const nav::PlanarPose odom{cycle.xy_yaw.x_m, cycle.xy_yaw.y_m, cycle.z_roll_pitch.z_m,
                               cycle.z_roll_pitch.roll_deg, cycle.z_roll_pitch.pitch_deg, cycle.xy_yaw.yaw_deg};
    const nav::PlanarPose map_odom{cycle.map_odom_xy_yaw.x_m, cycle.map_odom_xy_yaw.y_m, cycle.map_odom_z_roll_pitch.z_m,
                                   cycle.map_odom_z_roll_pitch.roll_deg, cycle.map_odom_z_roll_pitch.pitch_deg,
                                   cycle.map_odom_xy_yaw.yaw_deg};
    const Eigen::Isometry3d T_map_base = nav::to_isometry(map_odom) * nav::to_isometry(odom);
    const nav::PlanarPose decoded = nav::to_planar_pose(T_map_base);
    const Eigen::Isometry3d at_frame = T_base_cam * ref[index].T_world_cam * T_base_cam.inverse();
    const std::int64_t frame_ns = std::llround(ref[index].stamp_s * 1e6) * 1000;
    std::vector<Eigen::Isometry3d> candidates;
    bool wheels_passed_frame = false;
    for (long k = cycle.newest_wheel - 3; k <= cycle.newest_wheel + 2; ++k) {
      if (k < 0 || k >= static_cast<long>(recorded.size())) continue;
      const std::int64_t wheel_ns = recorded[static_cast<std::size_t>(k)].stamp_ns;
      if (wheel_ns > frame_ns + 20'000'000) wheels_passed_frame = true;
      Eigen::Isometry3d T;
      if (wheel_ns > frame_ns && wheel_motion(frame_ns, wheel_ns, T)) candidates.push_back(at_frame * T);
    }
    if (!wheels_passed_frame) candidates.push_back(at_frame);
    if (candidates.empty()) {
      fail("no wheel motion for the cycle naming frame " + std::to_string(index));
      continue;
    }
    Eigen::Isometry3d expected = candidates.front();
    for (const Eigen::Isometry3d& candidate : candidates) {
      if ((candidate.translation() - T_map_base.translation()).norm() < (expected.translation() - T_map_base.translation()).norm()) {
        expected = candidate;
      }
    }
    const double propagation_m = (expected.translation() - at_frame.translation()).norm();
    if (propagation_m > 0.001) ++propagated_cycles;
    largest_propagation_m = std::max(largest_propagation_m, propagation_m);
    const nav::PlanarPose expected_pose = nav::to_planar_pose(expected);
    const double position_m = (T_map_base.translation() - expected.translation()).norm();
    if (position_m > max_position_m && position_m > 0.001) {
      // The worst cycle so far, for the log: what it sent against what the bus showed before it.
      std::printf("cycle at %.3f s naming frame %zu (stamp %.3f s): %.1f mm from the nearest expected pose, %.1f mm from the "
                  "frame's; newest wheel frame on the bus #%ld (stamp %.3f s), %zu candidates\n",
                  static_cast<double>(cycle.stamp_ns - cycles.front().stamp_ns) * 1e-9, index, ref[index].stamp_s,
                  position_m * 1e3, (T_map_base.translation() - at_frame.translation()).norm() * 1e3, cycle.newest_wheel,
                  cycle.newest_wheel >= 0 ? static_cast<double>(recorded[static_cast<std::size_t>(cycle.newest_wheel)].stamp_ns) * 1e-9 : 0.0,
                  candidates.size());
    }
    max_position_m = std::max(max_position_m, position_m);
    max_rotation_deg = std::max(max_rotation_deg, rotation_angle_deg(T_map_base, expected));
    max_yaw_deg = std::max(max_yaw_deg, yaw_difference_deg(decoded.yaw_deg, expected_pose.yaw_deg));
    ++compared;
  }
  std::printf("compared %zu cycles naming %zu of %zu frames: max position difference %.3f mm, max rotation %.4f deg, max yaw %.4f deg\n",
              compared, frames_seen.size(), ref.size(), max_position_m * 1e3, max_rotation_deg, max_yaw_deg);
  if (max_position_m > 0.001) fail("a decoded position is more than 1 mm from the replayed trajectory");
  if (max_rotation_deg > 0.1 || max_yaw_deg > 0.1) fail("a decoded orientation is more than 0.1 deg from the replayed trajectory");
  if (frames_seen.size() != ref.size()) fail("not every frame's pose was sent");
  std::printf("cycles moved on by the wheels since their frame: %d (largest %.1f mm)\n", propagated_cycles,
              largest_propagation_m * 1e3);
  if (propagated_cycles < static_cast<int>(compared / 10)) fail("fewer than a tenth of the cycles were moved on by the wheels");

  // After the last frame, the watchdog turns the status LOST while heartbeats continue.
  std::optional<std::int64_t> first_lost_ns;
  std::int64_t last_new_frame_ns = cycles.front().stamp_ns;
  for (std::size_t i = 1; i < cycles.size(); ++i) {
    if (cycles[i].quality.frame_counter != cycles[i - 1].quality.frame_counter) last_new_frame_ns = cycles[i].stamp_ns;
  }
  for (const Cycle& cycle : cycles) {
    if (cycle.quality.status == nav::PoseStatus::kLost && cycle.stamp_ns > last_new_frame_ns) {
      first_lost_ns = cycle.stamp_ns;
      break;
    }
  }
  if (!first_lost_ns) {
    fail("no LOST pose cycle after the camera stopped");
  } else {
    const double delay_s = static_cast<double>(*first_lost_ns - last_new_frame_ns) * 1e-9;
    std::printf("LOST %.3f s after the last new pose (watchdog %.2f s)\n", delay_s, watchdog_s);
    if (delay_s < watchdog_s - 0.05) fail("LOST reported before the watchdog timeout");
    if (delay_s > watchdog_s + 0.5) fail("LOST reported more than 0.5 s after the watchdog timeout");
    if (cycles.back().quality.status != nav::PoseStatus::kLost) fail("the last pose cycle is not LOST");
    int lost_heartbeats = 0;
    for (const auto& [stamp_ns, heartbeat] : heartbeats) {
      if (stamp_ns > *first_lost_ns && heartbeat.camera_watchdog && heartbeat.status == nav::PoseStatus::kLost) ++lost_heartbeats;
    }
    std::printf("heartbeats while LOST: %d\n", lost_heartbeats);
    if (lost_heartbeats < 2) fail("heartbeats did not continue with the watchdog flag while LOST");
  }

  // The run flushed its own trajectory, equal to replay's, and the map.
  const std::filesystem::path run_out = arg["--run-out"];
  auto run_trajectory = eval::read_tum_trajectory(run_out / "trajectory.txt");
  if (!run_trajectory) {
    fail(run_trajectory.error());
  } else if (run_trajectory.value().size() != ref.size()) {
    fail("the run's trajectory has " + std::to_string(run_trajectory.value().size()) + " poses, replay's " + std::to_string(ref.size()));
  } else {
    double worst_m = 0.0;
    for (std::size_t i = 0; i < ref.size(); ++i) {
      worst_m = std::max(worst_m, (run_trajectory.value()[i].T_world_cam.translation() - ref[i].T_world_cam.translation()).norm());
    }
    std::printf("run trajectory vs replay trajectory: max %.6f mm\n", worst_m * 1e3);
    if (worst_m > 1e-6) fail("the run's trajectory differs from replay's");
  }
  for (const char* name : {"map.ply", "report.json"}) {
    if (!std::filesystem::is_regular_file(run_out / name)) fail(std::string("the run did not write ") + name);
  }
  // The wheel frames received from the bus were the prior of as many frames as can.log was in
  // replay (the report beside the reference trajectory).
  {
    const auto prior_frames = [](const std::filesystem::path& path) {
      std::ifstream in(path);
      std::stringstream text;
      text << in.rdbuf();
      if (text.str().find("\"wheels_used\": true") == std::string::npos) return -1L;
      return report_integer(path, "wheel_prior_frames");
    };
    const long run_priors = prior_frames(run_out / "report.json");
    const long replay_priors = prior_frames(std::filesystem::path(arg["--reference"]).parent_path() / "report.json");
    std::printf("wheel prior on %ld frames in the run (from the bus), %ld in replay (from can.log), of %zu\n", run_priors,
                replay_priors, ref.size());
    if (run_priors < 0 || run_priors != replay_priors || run_priors < static_cast<long>(ref.size()) * 9 / 10) {
      fail("the run did not take the wheel prior from the bus on the frames replay had it");
    }
  }
  std::printf("%s\n", g_failures == 0 ? "PASS" : "FAILED");
  return g_failures == 0 ? 0 : 1;
}
