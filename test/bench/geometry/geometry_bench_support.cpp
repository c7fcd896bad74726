#include "geometry_bench_support.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cmath>
#include <map>
#include <mutex>
#include <utility>

#include <unistd.h>

#include "rankslam/eval/metrics.hpp"
#include "rankslam/geometry/frontend.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/sim/simulator.hpp"
#include "rankslam/camera/depth_camera.hpp"

namespace rankslam::geometry::bench {

namespace fs = std::filesystem;

fs::path shared_recording(const std::string& name) {
#ifdef RANKSLAM_SHARED_DATA
  const fs::path root = fs::path(RANKSLAM_SHARED_DATA) / "tum" / name;
  if (fs::exists(root / "depth.txt") || fs::exists(root / "associations.txt")) return root;
#endif
  (void)name;
  return {};
}

namespace {

// Ground truth at `stamp_s`, interpolated between the two samples around it (translation
// linearly, rotation by slerp): the motion capture's 100 Hz samples are up to 5 ms from a depth
// stamp, which at fr1_rpy's 90°/s is already 0.45°.
std::optional<Eigen::Isometry3d> pose_at(const eval::Trajectory& gt, double stamp_s) {
  const auto after = std::lower_bound(gt.begin(), gt.end(), stamp_s,
                                      [](const eval::StampedPose& p, double t) { return p.stamp_s < t; });
  if (after != gt.end() && std::abs(after->stamp_s - stamp_s) < 1e-9) return after->T_world_cam;
  if (after == gt.end() || after == gt.begin()) return std::nullopt;
  const auto before = after - 1;
  if (after->stamp_s - before->stamp_s > 0.02) return std::nullopt;
  const double a = (stamp_s - before->stamp_s) / std::max(after->stamp_s - before->stamp_s, 1e-9);
  const Eigen::Quaterniond q0(before->T_world_cam.rotation());
  const Eigen::Quaterniond q1(after->T_world_cam.rotation());
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q0.slerp(a, q1).toRotationMatrix();
  T.translation() = (1.0 - a) * before->T_world_cam.translation() + a * after->T_world_cam.translation();
  return T;
}

}  // namespace

std::string load_depth_sequence(const fs::path& root, DepthSequence& sequence, int max_frames) {
  sequence = DepthSequence{};
  replay::Recording recording;
  if (std::string error = replay::open_recording(root, recording); !error.empty()) return error;
  eval::Trajectory gt;
  if (recording.ground_truth) {
    auto read = eval::read_tum_trajectory(*recording.ground_truth);
    if (!read.ok()) return read.error();
    gt = std::move(read).value();
    std::sort(gt.begin(), gt.end(),
              [](const eval::StampedPose& a, const eval::StampedPose& b) { return a.stamp_s < b.stamp_s; });
  }
  replay::ReplayOptions options;
  options.load_ir = false;
  options.max_frames = static_cast<std::uint32_t>(std::max(0, max_frames));
  replay::ReplayDepthCamera camera(recording, options);
  if (std::string error = camera.open(); !error.empty()) return error;
  hal::RgbdFrame frame;
  for (;;) {
    const hal::ReadStatus status = camera.read(frame, std::chrono::milliseconds(10000));
    if (status == hal::ReadStatus::kEndOfStream) break;
    if (status != hal::ReadStatus::kOk) {
      camera.close();
      return root.string() + ": replay stopped: " + std::string(hal::to_string(status));
    }
    const double stamp_s = recording.frames[frame.sequence].depth_stamp_s;
    sequence.stamps_s.push_back(stamp_s);
    sequence.depth.push_back(frame.depth.clone());
    sequence.T_world_cam.push_back(pose_at(gt, stamp_s));
  }
  camera.close();
  sequence.calibration = recording.calibration;
  if (sequence.depth.empty()) return root.string() + ": no frames";
  return {};
}

namespace {

// Simulated recordings written by this process, removed when it exits.
struct TemporaryRecordings {
  std::mutex mutex;
  std::map<std::string, fs::path> written;
  ~TemporaryRecordings() {
    for (const auto& [key, path] : written) {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  }
};

}  // namespace

std::string simulated_recording(const std::string& scene, int frames, std::uint64_t seed,
                                fs::path& root) {
  static TemporaryRecordings recordings;
  std::mutex& mutex = recordings.mutex;
  std::map<std::string, fs::path>& written = recordings.written;
  const std::string key = scene + "/" + std::to_string(frames) + "/" + std::to_string(seed);
  const std::lock_guard lock(mutex);
  if (const auto it = written.find(key); it != written.end()) {
    root = it->second;
    return {};
  }
  sim::SimulationOptions options;
  options.scene = scene;
  options.frames = frames;
  options.seed = seed;
  options.wheel_slip = false;
  options.out_dir = fs::temp_directory_path() /
                    ("rankslam_geometry_" + scene + "_" + std::to_string(frames) + "_" +
                     std::to_string(seed) + "_" + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(options.out_dir, ec);
  if (std::string error = sim::simulate_recording(options, nullptr); !error.empty()) return error;
  written[key] = options.out_dir;
  root = options.out_dir;
  return {};
}

std::string run_geometric_odometry(const fs::path& root, const GeometryConfig& config,
                                   OdometryResult& result, int max_frames) {
  result = OdometryResult{};
  replay::Recording recording;
  if (std::string error = replay::open_recording(root, recording); !error.empty()) return error;
  const camera::DepthCameraModel camera(recording.calibration.rgb, recording.calibration.depth_scale);
  GeometricFrontend frontend;
  if (std::string error = frontend.configure(camera, config); !error.empty()) return error;
  GeometricFeatures previous = frontend.make_features();
  GeometricFeatures current = frontend.make_features();
  bool have_previous = false;

  replay::ReplayOptions options;
  options.load_ir = false;
  options.max_frames = static_cast<std::uint32_t>(std::max(0, max_frames));
  replay::ReplayDepthCamera replay_camera(recording, options);
  if (std::string error = replay_camera.open(); !error.empty()) return error;
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  hal::RgbdFrame frame;
  double matches = 0.0;
  double inliers = 0.0;
  double keypoints = 0.0;
  double sampled = 0.0;
  int registrations = 0;
  for (;;) {
    const hal::ReadStatus status = replay_camera.read(frame, std::chrono::milliseconds(10000));
    if (status == hal::ReadStatus::kEndOfStream) break;
    if (status != hal::ReadStatus::kOk) {
      replay_camera.close();
      return root.string() + ": replay stopped: " + std::string(hal::to_string(status));
    }
    const auto start = std::chrono::steady_clock::now();
    const GeometryStatus extracted = frontend.extract(frame.depth, current);
    char line[256];
    std::snprintf(line, sizeof line, "%4d %-18s dense %6d phi %.4f leaf %.4f sampled %5d cand %5d kp %4d",
                  result.frames, std::string(to_string(extracted)).c_str(), current.dense_points,
                  static_cast<double>(current.resolution_m), static_cast<double>(current.voxel_leaf_m),
                  current.sampled_points, current.keypoint_candidates, current.count);
    std::string log = line;
    const KeypointStats& stats = frontend.last_keypoint_stats();
    for (int o = 0; o < stats.orientations; ++o) {
      std::snprintf(line, sizeof line, " g%d", stats.group_size[static_cast<std::size_t>(o)]);
      log += line;
    }
    if (extracted != GeometryStatus::kOk) {
      ++result.failed_extractions;
    } else {
      keypoints += current.count;
      sampled += current.sampled_points;
      if (have_previous) {
        const FrameRegistration registration = frontend.register_frames(previous, current);
        ++registrations;
        matches += registration.matches;
        inliers += registration.inliers;
        std::snprintf(line, sizeof line, " | %-20s matches %4d inliers %4d", 
                      std::string(to_string(registration.status)).c_str(), registration.matches,
                      registration.inliers);
        log += line;
        if (registration.ok) {
          T_world_cam = T_world_cam * registration.T_previous_current;
        } else {
          ++result.failed_registrations;
        }
      }
      std::swap(previous, current);
      have_previous = true;
    }
    result.frame_log.push_back(log);
    result.frame_ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    result.estimate.push_back(
        eval::StampedPose{recording.frames[frame.sequence].depth_stamp_s, T_world_cam});
    ++result.frames;
  }
  replay_camera.close();
  const int extracted_frames = result.frames - result.failed_extractions;
  if (extracted_frames > 0) {
    result.mean_keypoints = keypoints / extracted_frames;
    result.mean_sampled_points = sampled / extracted_frames;
  }
  if (registrations > 0) {
    result.mean_matches = matches / registrations;
    result.mean_inliers = inliers / registrations;
  }
  if (recording.ground_truth) {
    auto gt = eval::read_tum_trajectory(*recording.ground_truth);
    if (!gt.ok()) return gt.error();
    auto evaluated = eval::evaluate(gt.value(), result.estimate);
    if (!evaluated.ok()) return evaluated.error();
    result.ate_rmse_m = evaluated.value().ate.translation_m.rmse;
    if (evaluated.value().rpe) {
      result.rpe_translation_m_per_s = evaluated.value().rpe->translation_m_per_s.rmse;
      result.rpe_rotation_deg_per_s = evaluated.value().rpe->rotation_deg_per_s.rmse;
    }
  }
  return {};
}

}  // namespace rankslam::geometry::bench
