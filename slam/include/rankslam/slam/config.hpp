#pragma once

#include <cstdint>
#include <string_view>

namespace rankslam::slam {

/// Which registration the SLAM loop runs.
enum class Mode : std::uint8_t {
  kBaseline,     ///< ORB + fixed-threshold RANSAC: the comparator the thesis measures MSSE against.
  kPhotometric,  ///< ORB + MSSE (ALGORITHMS.md §2).
  kGeometric,    ///< IS3D + SHOT + MSSE, depth only (§3–4).
  kFused,        ///< Weighted photometric + geometric MSSE (§5).
};

[[nodiscard]] constexpr std::string_view to_string(Mode mode) {
  switch (mode) {
    case Mode::kBaseline: return "baseline";
    case Mode::kPhotometric: return "photometric";
    case Mode::kGeometric: return "geometric";
    case Mode::kFused: return "fused";
  }
  return "unknown";
}

/// Parameters of the SLAM loop. Each is declared once, in visit_parameters(), with its range,
/// unit and meaning; the configuration loader and the start-up printout both walk that list.
struct SlamConfig {
  Mode mode = Mode::kBaseline;

  int orb_features = 1000;
  double orb_scale_factor = 1.2;
  int orb_levels = 8;
  int orb_fast_threshold = 20;
  int max_hamming_distance = 64;
  double min_depth_m = 0.3;
  double max_depth_m = 4.0;
  double depth_noise_per_m = 1.425e-3;
  double keypoint_sigma_px = 0.5;
  double ransac_threshold_m = 0.02;
  int ransac_iterations = 1000;
  int min_inliers = 12;
  double max_step_translation_m = 0.5;
  double max_step_rotation_deg = 45.0;
  double keyframe_translation_m = 0.25;
  double keyframe_rotation_deg = 15.0;
  double map_voxel_m = 0.02;
  int map_max_points = 2'000'000;
  int map_points_per_keyframe = 5000;
  int seed = 1;

  /// Calls visit(name, field, min, max, unit, doc) for every parameter.
  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("orb_features", orb_features, 100, 20000, "", "ORB keypoints detected per frame");
    visit("orb_scale_factor", orb_scale_factor, 1.05, 2.0, "", "ORB pyramid scale between levels");
    visit("orb_levels", orb_levels, 1, 16, "", "ORB pyramid levels");
    visit("orb_fast_threshold", orb_fast_threshold, 1, 100, "", "FAST corner threshold");
    visit("max_hamming_distance", max_hamming_distance, 1, 256, "bit", "largest descriptor distance of a match");
    visit("min_depth_m", min_depth_m, 0.0, 10.0, "m", "nearest depth a feature may have");
    visit("max_depth_m", max_depth_m, 0.1, 20.0, "m", "farthest depth a feature may have");
    visit("depth_noise_per_m", depth_noise_per_m, 0.0, 0.1, "1/m",
          "a in the depth noise model sigma_z = a*z^2 (Kinect: 1.425e-3)");
    visit("keypoint_sigma_px", keypoint_sigma_px, 0.01, 10.0, "px",
          "keypoint localisation error at the finest pyramid level");
    visit("ransac_threshold_m", ransac_threshold_m, 0.001, 1.0, "m", "baseline RANSAC inlier threshold");
    visit("ransac_iterations", ransac_iterations, 10, 100000, "", "baseline RANSAC hypotheses");
    visit("min_inliers", min_inliers, 3, 10000, "", "fewer inliers mark the frame failed");
    visit("max_step_translation_m", max_step_translation_m, 0.01, 10.0, "m",
          "larger frame-to-frame translation is rejected as a failure");
    visit("max_step_rotation_deg", max_step_rotation_deg, 1.0, 180.0, "deg",
          "larger frame-to-frame rotation is rejected as a failure");
    visit("keyframe_translation_m", keyframe_translation_m, 0.01, 10.0, "m", "translation that starts a key-frame");
    visit("keyframe_rotation_deg", keyframe_rotation_deg, 1.0, 180.0, "deg", "rotation that starts a key-frame");
    visit("map_voxel_m", map_voxel_m, 0.001, 1.0, "m", "map voxel edge; points in one voxel are merged");
    visit("map_max_points", map_max_points, 1000, 50'000'000, "", "capacity of the map");
    visit("map_points_per_keyframe", map_points_per_keyframe, 100, 307200, "", "points sampled per key-frame");
    visit("seed", seed, 0, 2147483647, "", "random seed: equal seeds give equal results");
  }
};

}  // namespace rankslam::slam
