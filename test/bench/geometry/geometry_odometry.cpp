// geometry_odometry: depth-only frame-to-frame odometry with the geometric front-end over one
// recording, printing accuracy and per-frame time. For tuning and reports; the bench tests
// assert the accuracy.
//
//   geometry_odometry <recording-dir | sim:<scene>[:frames]> [key=value ...]
//
// key is any GeometryConfig parameter (visit_parameters), or method=is3d|ros|uniform,
// ranking=saliency|farthest|nearest, frames=N.

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "geometry_bench_support.hpp"
#include "rankslam/geometry/config.hpp"

using namespace rankslam::geometry;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s <recording | sim:<scene>[:frames]> [key=value ...]\n", argv[0]);
    return 2;
  }
  GeometryConfig config;
  int max_frames = 0;
  bool verbose = false;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    const auto eq = arg.find('=');
    if (eq == std::string::npos) {
      std::fprintf(stderr, "expected key=value: %s\n", arg.c_str());
      return 2;
    }
    const std::string key = arg.substr(0, eq);
    const std::string value = arg.substr(eq + 1);
    if (key == "method") {
      config.keypoint_method = value == "ros"       ? KeypointMethod::kRos
                               : value == "uniform" ? KeypointMethod::kUniform
                                                    : KeypointMethod::kIs3d;
      continue;
    }
    if (key == "ranking") {
      config.is3d_ranking = value == "nearest"    ? Is3dRanking::kNearestToOrientations
                            : value == "farthest" ? Is3dRanking::kFarthestFromOrientations
                                                  : Is3dRanking::kLocalSaliency;
      continue;
    }
    if (key == "verbose") {
      verbose = value == "1";
      continue;
    }
    if (key == "frames") {
      max_frames = std::atoi(value.c_str());
      continue;
    }
    bool found = false;
    config.visit_parameters([&](std::string_view name, auto& field, auto, auto, auto, auto) {
      if (name == key) {
        field = static_cast<std::remove_reference_t<decltype(field)>>(std::atof(value.c_str()));
        found = true;
      }
    });
    if (!found) {
      std::fprintf(stderr, "unknown parameter %s\n", key.c_str());
      return 2;
    }
  }
  if (const auto bad = config.validate(); !bad.empty()) {
    std::fprintf(stderr, "invalid parameter %.*s\n", static_cast<int>(bad.size()), bad.data());
    return 2;
  }
  std::filesystem::path root = argv[1];
  const std::string source = argv[1];
  if (source.rfind("sim:", 0) == 0) {
    std::string scene = source.substr(4);
    int frames = 0;
    if (const auto colon = scene.find(':'); colon != std::string::npos) {
      frames = std::atoi(scene.substr(colon + 1).c_str());
      scene = scene.substr(0, colon);
    }
    if (std::string error = bench::simulated_recording(scene, frames, 1, root); !error.empty()) {
      std::fprintf(stderr, "%s\n", error.c_str());
      return 1;
    }
  }
  bench::OdometryResult result;
  if (std::string error = bench::run_geometric_odometry(root, config, result, max_frames);
      !error.empty()) {
    std::fprintf(stderr, "%s\n", error.c_str());
    return 1;
  }
  if (verbose) {
    for (const std::string& line : result.frame_log) std::printf("%s\n", line.c_str());
  }
  std::vector<double> ms = result.frame_ms;
  std::sort(ms.begin(), ms.end());
  const double median = ms.empty() ? 0.0 : ms[ms.size() / 2];
  std::printf(
      "recording %s\nmethod %s\nframes %d\nfailed_extractions %d\nfailed_registrations %d\n"
      "mean_sampled_points %.0f\nmean_keypoints %.1f\nmean_matches %.1f\nmean_inliers %.1f\n"
      "ate_rmse_m %.4f\nrpe_trans_m_per_s %.4f\nrpe_rot_deg_per_s %.3f\nmedian_frame_ms %.2f\n",
      root.string().c_str(), std::string(to_string(config.keypoint_method)).c_str(), result.frames,
      result.failed_extractions, result.failed_registrations, result.mean_sampled_points,
      result.mean_keypoints, result.mean_matches, result.mean_inliers, result.ate_rmse_m,
      result.rpe_translation_m_per_s, result.rpe_rotation_deg_per_s, median);
  return 0;
}
