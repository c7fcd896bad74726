#pragma once

#include "rankslam/geometry/config.hpp"
#include "rankslam/nav/wheel_arbiter.hpp"

#include <cstdint>
#include <optional>
#include <string_view>

namespace rankslam::slam {

/// Which registration the SLAM loop runs.
enum class Mode : std::uint8_t {
  kBaseline,     ///< ORB + fixed-threshold RANSAC: the comparator the thesis measures MSSE against.
  kPhotometric,  ///< ORB + MSSE (docs/methods.md §2).
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

/// Optional dense refinement after the feature registration (docs/methods.md §2).
enum class IcpMode : std::uint8_t {
  kOff,
  kPointToPoint,  ///< Closest points, closed-form rigid fit per iteration (Besl & McKay 1992).
  kPointToPlane,  ///< Closest points, distance along the target normal (Chen & Medioni 1992).
};

[[nodiscard]] constexpr std::string_view to_string(IcpMode mode) {
  switch (mode) {
    case IcpMode::kOff: return "off";
    case IcpMode::kPointToPoint: return "point_to_point";
    case IcpMode::kPointToPlane: return "point_to_plane";
  }
  return "unknown";
}

/// "off", "point_to_point" or "point_to_plane"; nullopt for anything else.
[[nodiscard]] constexpr std::optional<IcpMode> parse_icp_mode(std::string_view text) {
  for (const IcpMode mode : {IcpMode::kOff, IcpMode::kPointToPoint, IcpMode::kPointToPlane}) {
    if (text == to_string(mode)) return mode;
  }
  return std::nullopt;
}

/// Which ORB implementation extracts the photometric features.
enum class OrbImplementation : std::uint8_t {
  kFixedMemory,  ///< rankslam's OrbExtractor: memory fixed at set-up, nothing allocated per frame.
  kOpenCv,       ///< OpenCV's cv::ORB, which allocates on every frame: the measured reference.
};

/// Parameters of the SLAM loop. Each is declared once, in visit_parameters(), with its range,
/// unit and meaning; the configuration loader and the start-up printout both walk that list.
/// `mode` and `icp_mode` are named choices, set apart from the numeric parameters.
struct SlamConfig {
  Mode mode = Mode::kBaseline;
  IcpMode icp_mode = IcpMode::kOff;
  /// Not read from configuration files: OpenCV's ORB is kept for side-by-side measurements.
  OrbImplementation orb_implementation = OrbImplementation::kFixedMemory;

  int orb_features = 1000;
  double orb_scale_factor = 1.2;
  int orb_levels = 8;
  int orb_fast_threshold = 20;
  int max_hamming_distance = 64;
  double min_depth_m = 0.3;
  double max_depth_m = 4.0;
  // Effective depth error at a keypoint, sigma_z = a*z^2. Khoshelham & Elberink's 1.425e-3 is
  // the Kinect's random noise on a plane; at keypoints (corners, texture edges) the colour-depth
  // registration and the two sensors' timing add errors that also grow with z^2. With 5e-3 the
  // refit weights follow 1/z^4 and near points dominate. fr1_rpy_head photometric ATE over seeds
  // 1-6: mean 0.0281 m with 5e-3, 0.0300 m with 1.425e-3; simulated office scenes 0.006-0.012 m
  // either way.
  double depth_noise_per_m = 5e-3;
  double keypoint_sigma_px = 0.5;
  // Rolling shutter of the colour camera: rows are exposed one after another over this time, so
  // under fast rotation each keypoint is seen from a slightly different pose. Points are moved to
  // the frame's mid-exposure pose with the constant-velocity motion. fr1_rpy_head (up to
  // 3 deg/frame), ATE over seeds 1-6: mean 0.0396 m with 0, 0.0326 m with 10, 0.0281 m with
  // 15 ms. A global-shutter camera (the simulator's) takes 0; 15 ms costs it nothing measurable
  // (simulated office scenes 0.006-0.012 m either way).
  double rolling_shutter_readout_ms = 15.0;
  double ransac_threshold_m = 0.02;
  int ransac_iterations = 1000;
  int msse_hypotheses = 1000;
  // MSSE kappa. With 0.1 the least-k-th-order fit latches in 1-5 % of the frames onto a small
  // subset that fits far too well (points on one plane whose quantised depths are identical in
  // both frames) and segmentation stops at k* ~ k0. 0.3 removes most of those; the smallest true
  // inlier fraction seen on fr1_rpy_head is 0.42. ATE, 0.3 vs 0.1: fr1_rpy_head seeds 1-6 mean
  // 0.0281 vs 0.0316 m, simulated dark office 0.011 vs 0.020 m.
  double msse_min_inlier_fraction = 0.3;
  // MSSE rounds of re-segmenting and refitting after the first refit. The thesis refits once (0);
  // more rounds shrink the inlier set towards its tightest core on real data: fr1_rpy_head ATE
  // over seeds 1-6 mean 0.0281 m with 0, 0.0307 m with 3 (0.025-0.044).
  int msse_refine_iterations = 0;
  int min_inliers = 12;
  double max_step_translation_m = 0.5;
  double max_step_rotation_deg = 45.0;
  double max_deviation_translation_m = 0.1;
  double max_deviation_rotation_deg = 10.0;
  // Failed frames take the constant-velocity prediction for this many frames in a row (half a
  // second at 30 Hz: long enough to bridge a blur or a passing occluder); after that the pose is
  // held. Extrapolating further would carry a robot that stopped in front of a blank wall off at
  // its last speed: on the simulated corridor loop, unbounded extrapolation over 400 failed
  // frames reached 1e40 m.
  int max_extrapolated_frames = 15;
  // Frame-to-key-frame tracking (see SlamLoop). ATE over fr1_rpy_head seeds 1-6 / simulated
  // dark office: 0.3: 0.046 / 0.014 m, 0.5: 0.028 / 0.011 m, 0.7: 0.036 / 0.026 m, 1.0 (a new
  // key-frame almost every frame): 0.039 / 0.059 m.
  double reference_min_overlap = 0.5;
  // A registration against the reference whose noise scale (MotionEstimate::noise_scale) exceeds
  // this also registers against the previous frame and keeps the better fit (the frame then
  // becomes the reference). Tracking registrations on fr1_rpy_head mostly have 0.5-1.5; fused ATE
  // over seeds 1-5: 1.5: 0.0192 m, 2.0: 0.0200 m, 3.0: 0.0201 m, off: 0.0221 m.
  double reference_max_noise_scale = 2.0;
  double keyframe_translation_m = 0.25;
  double keyframe_rotation_deg = 15.0;
  double map_voxel_m = 0.02;
  int map_max_points = 2'000'000;
  int map_points_per_keyframe = 5000;
  // Dark scenes (docs/methods.md §2). Lit indoor scenes read a mean grey level of about 100-160
  // (fr1_rpy_head 109-161, fr1_desk 141-146, simulated office 98-124, poster wall 126-140); the
  // simulated dark office reads 9-10, images of sensor noise. 30 sits well clear of both: a dim
  // but lit room stays on colour, a room with the lights off goes to IR. The IR image gets its
  // own FAST threshold: after the pre-processing its contrast is a fraction of a lit colour
  // image's (20 finds ~90 corners on the dark office and 16 of 90 frames fail, ATE 0.15 m; 8
  // finds ~700, none fails, ATE 0.011 m).
  double ir_switch_brightness = 30.0;
  int ir_orb_fast_threshold = 8;
  int icp_max_iterations = 20;
  double icp_max_correspondence_m = 0.05;
  double icp_voxel_m = 0.02;
  double icp_max_depth_m = 4.0;
  int icp_pixel_stride = 2;
  int icp_max_source_points = 4000;
  double icp_max_correction_m = 0.02;
  double icp_max_correction_deg = 1.0;
  /// The wheel/vision arbiter (SlamLoop::process with a MotionPrior).
  nav::WheelArbiterConfig wheels;
  // Fused mode (docs/methods.md §6). Geometric keypoints are voxel centroids; their position noise
  // in the combined MSSE gets this multiple of the voxel leaf per frame on top of the depth noise.
  // Without it a geometric match counted as 2-4x more precise than an ORB match and pulled the
  // estimate. fr1_rpy_head fused ATE, mean over seeds 1-5 (with the keypoints' rolling-shutter
  // correction and the key-frames' velocities in loop closure): 0.032 m with 1, 0.025 m with 2;
  // without loop closure 0.043 and 0.028 m. With 2, simulated office / zigzag-plain / poster-wall
  // 0.0077 / 0.0007 / 0.0031 m, the corridor loops with wheels (seeds 1-5) 0.006-0.021 m.
  double fused_geometric_leaf_sigma = 2.0;
  // Below this many photometric inliers the fused estimate is refined by the geometric ICP
  // (coarse and fine). Without loop closure, fused ATE without ICP / with it always / below 100:
  // simulated office 0.014 / 0.004 / 0.010 m, zigzag-plain 0.532 / 0.0007 / 0.0007 m,
  // poster-wall 0.005 / 0.96 (ICP slides on the one plane) / 0.005 m. On fr1_rpy_head the ICP
  // only hurts (Kinect noise on a cluttered desk): with loop closure, ATE 0.033 m below 100,
  // 0.030 m below 30, while the simulated scenes stay at 0.0085 / 0.0007 / 0.0027 m. 0: never.
  int fused_icp_below_photometric_inliers = 30;
  // The refinement also runs where the photometric inliers are many but fix the rotation poorly:
  // a poster's worth of corners 2-3 m away sets tilt and height only together (simulated
  // corridor: 40-60 inliers on one notice, registrations 1-2 deg and 5 cm off). Above this
  // rotation uncertainty (1 sigma, from the inliers' information and their noise scale), the ICP
  // refines. fr1_rpy_head's photometric registrations: median 0.20 deg, 90th percentile 0.64;
  // the corridor's on its notices: median 1.8 deg, 10th percentile 0.68. Corridor loop (seed 1,
  // no wheels), ATE without / with loop closure: 0.226 / 0.118 m with 0, 0.127 / 0.096 m with 1;
  // fr1_rpy_head seeds 1-5 unchanged (0.0193-0.0207 m). 0: never.
  double fused_icp_above_rotation_sigma_deg = 1.0;
  // That refinement where the view fixes only part of the motion (a lone wall fixes its
  // distance and tilt, a corridor everything but the travel along it): the ICP holds a prior
  // there. A feature estimate may be the prior only when it is one: at least min_inliers
  // inliers fitting within fused_max_noise_scale of their predicted noise (a dozen matches of
  // noise "fit" with a scale of 10-20: on the simulated corridor loop, seed 1, 96 % of the
  // estimates above 5 were off by tens of degrees), and, unless the photometric kind has
  // min_inliers inliers of its own, geometric inliers that leave a plane by
  // fused_min_geometric_thickness_m (SHOT describes surface shape, and on one plane every
  // keypoint looks alike: turning towards a blank wall, coplanar inliers set the camera 10-50 cm
  // along it). Otherwise the prior is the previous frame's pose: what the view cannot see is
  // taken to stand still. (Constant velocity there instead turned one wrongly registered step
  // into a drift without end: corridor loop seeds 1 and 2, ATE 1.39 and 1.31 m against 0.21 and
  // 0.24 m.) fused_icp_prior_sigma_* is the prior's strength on the step from its pose: the
  // camera's for a feature estimate, the robot base's at rest (through the calibration's
  // T_base_cam, so that a base turning in place may swing the camera on its mount).
  // On a differential-drive robot (the calibration has `wheels`: a planar base, whether or not
  // its encoders are read) the prior is the base's drivable step instead: the constant-velocity
  // prediction kept to forward travel and a turn, no sideways slide, no change in height, roll or
  // pitch, combined with the feature estimate when it is a registration (each by its
  // information). A base cannot leave the floor, and between two frames it keeps about its speed;
  // the feature estimate keeps that speed honest. Corridor loop (seed 1, no wheels), ATE without
  // / with loop closure: 0.196 / 0.161 m (one false closure) with 0, 0.127 / 0.096 m with 1.
  // (The drivable step alone, without the feature estimate, ran away along the corridor: 2.4 m;
  // the full constant-velocity step as the prior tilted the camera by 30 deg facing the end wall,
  // whose one plane leaves the turn about its normal free.) 0: the prior above on every platform.
  int fused_icp_base_kinematics = 1;
  // The translation strength: on the corridor loop (no wheels, SLAM seed 1, ATE without / with
  // loop closure) 1 cm gave 0.127 / 0.087 m on recording seed 1 and 0.187 / 0.106 m on seed 2;
  // 5 mm gives 0.095 / 0.059 m and 0.092 / 0.050 m; 3 cm gave 0.218 / 0.177 m. fr1_rpy_head
  // (seeds 1-2) and the simulated office, zigzag-plain and poster-wall are unchanged.
  double fused_icp_prior_sigma_m = 0.005;
  double fused_icp_prior_sigma_deg = 1.0;
  double fused_max_noise_scale = 2.0;
  double fused_min_geometric_thickness_m = 0.1;
  // An ICP-refined registration whose feature inliers fall below min_inliers is accepted on
  // this many point-to-plane inliers (a lone wall at 1 m gives 1 000-4 000).
  int min_icp_inliers = 300;
  // Back-end (docs/methods.md §8, §10–§11): key-frame store, loop closure, pose graph.
  // Stored key-frames (features, map points, graph node, sampled cloud); when full, one far from
  // the camera with the fewest loop closures is retired (KeyframeStore::retirement_candidate).
  // About 1 MB each.
  int keyframe_capacity = 128;
  // Sampled points (voxel centroids, normals, pixels) each key-frame keeps, so that a loop
  // closure whose photometric inliers are weak (see fused_icp_below_photometric_inliers and
  // fused_icp_above_rotation_sigma_deg) is refined by the geometric ICP against it, as tracking
  // is. Evenly strided down to this many. 0: closures on feature matches alone, where weak ones
  // are not taken. About 36 bytes a point. The corridor loop's closures all have weak
  // photometric inliers: with 0 it closes nowhere (corridors 1 and 2, seed 1, no wheels: ATE
  // 0.127 and 0.187 m), with 6000 it closes 8 and 6 times, none false, the worst 3 cm off
  // (0.096 and 0.146 m). Unrefined, such closures were 2-9 cm and 0.5-1.7 deg off.
  int keyframe_cloud_points = 6000;
  // Threads that share the per-frame loops (MSSE's hypotheses; the geometric front-end's cloud,
  // keypoints, descriptors, matching and ICP), the tracking thread included: the robot
  // computer's two cores. 1 keeps all on the tracking thread. The estimates are the same for any
  // count.
  int threads = 2;
  // Loop-closure candidates: stored key-frames other than the last loop_min_keyframe_gap, within
  // loop_search_radius_m / loop_search_rotation_deg of the new key-frame, both bounds widened by
  // the drift allowed over the path travelled since the candidate (loop_drift_per_m of it, and
  // loop_drift_deg_per_m); the loop_max_candidates nearest are registered.
  int loop_min_keyframe_gap = 5;
  double loop_search_radius_m = 0.5;
  double loop_search_rotation_deg = 30.0;
  double loop_drift_per_m = 0.1;
  double loop_drift_deg_per_m = 3.0;
  int loop_max_candidates = 3;
  // Candidates registered per frame, from the key-frame's own frame on (0: all of them in the
  // key-frame's frame). Each is a full fused registration: spread over the next frames they add
  // one registration's time to a frame instead of loop_max_candidates', which lowers the longest
  // frames and raises the median (more frames carry one; docs/results.md §2.2).
  int loop_candidates_per_frame = 0;
  // Adaptive threshold ε on k_P + k_G (docs/methods.md §10): initial value until two closures exist
  // (lean low: the thesis saw 68-207), and T_ε.
  double loop_initial_threshold = 60.0;
  double loop_threshold_deviations = 1.0;
  // Protection against false closures: the registered relative pose may differ from the graph's
  // by at most this plus the drift allowance; the inliers must spread at least this far
  // (square root of the middle eigenvalue of their covariance: not a line or a blob).
  double loop_max_correction_m = 0.1;
  double loop_max_correction_deg = 5.0;
  double loop_min_inlier_spread_m = 0.05;
  // A closure corrects the chain accumulated since its stored key-frame, so it must be more
  // precise than tracking needs: it is refined by the geometric ICP on the key-frame's stored
  // cloud (keyframe_cloud_points) when its photometric inliers fix the rotation worse than this
  // (or are fewer than fused_icp_below_photometric_inliers). On the corridor loop (seed 1) a
  // closure on 44 inliers of one notice, left unrefined under fused_icp_above_rotation_sigma_deg,
  // was 9 cm and 1.6 deg off. 0: only the inlier count decides.
  double loop_icp_above_rotation_sigma_deg = 0.5;
  // A refined closure is taken only where the surfaces fix every direction at least this fraction
  // as well as the feature estimate they refine (least generalised eigenvalue of the ICP data
  // information against the prior's). Facing the blank wall at the loop's stop, or seeing only the
  // floor, the ICP leaves the closure where the few features put it, 4-16 cm off; dropping those
  // took the corridor loop (seeds 1 and 2 of both recordings) from 0.095/0.136/0.118/0.080 m to
  // 0.087/0.106/0.067/0.066 m ATE (0.03: 0.088/0.105, 0.3: 0.087/0.111, 1: 0.087/0.121 on seed 1).
  double loop_icp_min_information_ratio = 0.1;
  // Edge information from the inlier count (graph::information_from_matches): the error of a
  // registration on one match whose inliers fit as their predicted noise says; a registration
  // that fits worse has its information divided by its noise scale squared
  // (SlamLoop::registration_information).
  double graph_match_sigma_m = 0.02;
  double graph_match_sigma_deg = 1.0;
  // Sequential edges of key-frames registered with the ICP refinement: the feature inliers'
  // information (from their noise) plus the surfaces' point-to-plane information at this error
  // per fully constraining direction, so that a loop closure bends the chain where the view left
  // the motion free (along a featureless corridor) rather than evenly.
  double graph_icp_sigma_m = 0.005;
  int graph_iterations = 20;
  // Wheel edges between consecutive key-frames (with a wheel prior on every frame between them):
  // the wheel motion with its propagated covariance, plus this floor on the motion a planar base
  // does not measure. 0 m: no wheel edges. The floor adds to every axis, so it must stay below
  // the wheels' own noise over a key-frame step (1 cm/m over 25 cm: 5 mm) or it buries it:
  // 1 cm / 0.5 deg per edge is 4 cm/m, and gave 3.1 cm ATE on the corridor loop against 1.7 cm
  // with 1 mm / 0.05 deg.
  double graph_wheel_floor_m = 0.001;
  double graph_wheel_floor_deg = 0.05;
  // On a differential-drive base (the calibration has `wheels`, whether or not they are read),
  // consecutive key-frames are also joined by an edge that holds the base's height, roll and
  // pitch (a base stays on its floor) to these. Vision alone lets them drift with every small
  // pitch error (corridor loop, seed 1, no wheels: 0.30 m of height over the 21 m loop), and a
  // loop closure then spreads the height error at the closure over the whole loop. With loop
  // closure on that recording, height error (RMS after alignment) 0.022 -> 0.002 m and ATE
  // 0.058 -> 0.054 m. Without a closure the graph is never optimised and nothing changes.
  // 0: no such edges.
  double graph_planar_sigma_m = 0.005;
  double graph_planar_sigma_deg = 0.2;
  int seed = 1;

  /// The depth-only front-end of the geometric mode (docs/methods.md §3–§5); its own parameter list.
  geometry::GeometryConfig geometry;

  /// Calls visit(name, field, min, max, unit, doc) for every numeric parameter.
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
          "a in the keypoint depth error model sigma_z = a*z^2 (Kinect random noise alone: 1.425e-3)");
    visit("keypoint_sigma_px", keypoint_sigma_px, 0.01, 10.0, "px",
          "keypoint localisation error at the finest pyramid level");
    visit("rolling_shutter_readout_ms", rolling_shutter_readout_ms, 0.0, 100.0, "ms",
          "colour camera readout time, top to bottom row (0: global shutter)");
    visit("ransac_threshold_m", ransac_threshold_m, 0.001, 1.0, "m", "baseline RANSAC inlier threshold");
    visit("ransac_iterations", ransac_iterations, 10, 100000, "", "baseline RANSAC hypotheses");
    visit("msse_hypotheses", msse_hypotheses, 10, 100000, "", "MSSE minimal-sample hypotheses per registration");
    visit("msse_min_inlier_fraction", msse_min_inlier_fraction, 0.01, 0.9, "",
          "MSSE kappa: least inlier fraction assumed among the matches");
    visit("msse_refine_iterations", msse_refine_iterations, 0, 100, "",
          "MSSE re-segment-and-refit rounds after the first refit (thesis: 0)");
    visit("min_inliers", min_inliers, 3, 10000, "", "fewer inliers mark the frame failed");
    visit("max_step_translation_m", max_step_translation_m, 0.01, 10.0, "m",
          "larger frame-to-frame translation is rejected as a failure");
    visit("max_step_rotation_deg", max_step_rotation_deg, 1.0, 180.0, "deg",
          "larger frame-to-frame rotation is rejected as a failure");
    visit("max_deviation_translation_m", max_deviation_translation_m, 0.001, 10.0, "m",
          "a frame whose motion differs more from the previous frame's is rejected as a failure");
    visit("max_deviation_rotation_deg", max_deviation_rotation_deg, 0.1, 180.0, "deg",
          "a frame whose rotation differs more from the previous frame's is rejected as a failure");
    visit("max_extrapolated_frames", max_extrapolated_frames, 0, 1000, "",
          "failed frames in a row that take the constant-velocity prediction; later ones hold the pose");
    visit("reference_min_overlap", reference_min_overlap, 0.0, 1.0, "",
          "a frame becomes the tracking key-frame when its inliers fall below this fraction of the first frame's against the key-frame");
    visit("reference_max_noise_scale", reference_max_noise_scale, 1.0, 1000.0, "",
          "a worse-fitting registration against the tracking key-frame also tries the previous frame");
    visit("keyframe_translation_m", keyframe_translation_m, 0.01, 10.0, "m", "translation that starts a map key-frame");
    visit("keyframe_rotation_deg", keyframe_rotation_deg, 1.0, 180.0, "deg", "rotation that starts a map key-frame");
    visit("map_voxel_m", map_voxel_m, 0.001, 1.0, "m", "map voxel edge; points in one voxel are merged");
    visit("map_max_points", map_max_points, 1000, 50'000'000, "", "capacity of the map");
    visit("map_points_per_keyframe", map_points_per_keyframe, 100, 307200, "", "points sampled per key-frame");
    visit("ir_switch_brightness", ir_switch_brightness, 0.0, 255.0, "level",
          "mean grey level of the colour image below which features come from the IR image (0: never)");
    visit("ir_orb_fast_threshold", ir_orb_fast_threshold, 1, 100, "", "FAST corner threshold on the IR image");
    visit("icp_max_iterations", icp_max_iterations, 1, 100, "", "ICP iterations at most");
    visit("icp_max_correspondence_m", icp_max_correspondence_m, 0.001, 1.0, "m", "ICP pairs farther apart are dropped");
    visit("icp_voxel_m", icp_voxel_m, 0.001, 0.5, "m", "voxel edge of the ICP cloud filter");
    visit("icp_max_depth_m", icp_max_depth_m, 0.1, 20.0, "m", "farther depth is left out of the ICP cloud");
    visit("icp_pixel_stride", icp_pixel_stride, 1, 16, "px", "every n-th pixel in u and v feeds the ICP voxel grid");
    visit("icp_max_source_points", icp_max_source_points, 100, 307200, "", "source points used per ICP iteration");
    visit("icp_max_correction_m", icp_max_correction_m, 0.0, 1.0, "m",
          "larger ICP corrections of the feature estimate are discarded");
    visit("icp_max_correction_deg", icp_max_correction_deg, 0.0, 90.0, "deg",
          "larger ICP rotation corrections of the feature estimate are discarded");
    wheels.visit_parameters(visit);
    visit("fused_geometric_leaf_sigma", fused_geometric_leaf_sigma, 0.0, 10.0, "leaf",
          "fused mode: position noise of a geometric keypoint added per frame, in voxel leaves");
    visit("fused_icp_below_photometric_inliers", fused_icp_below_photometric_inliers, 0, 100000, "",
          "fused mode: fewer photometric inliers than this call for the geometric ICP refinement (0: never)");
    visit("fused_icp_above_rotation_sigma_deg", fused_icp_above_rotation_sigma_deg, 0.0, 180.0, "deg",
          "fused mode: photometric inliers that fix the rotation worse than this also call for the ICP refinement (0: never)");
    visit("fused_icp_base_kinematics", fused_icp_base_kinematics, 0, 1, "",
          "fused mode on a differential-drive robot: the ICP prior is the base's drivable step with the feature estimate");
    visit("fused_icp_prior_sigma_m", fused_icp_prior_sigma_m, 1e-4, 10.0, "m",
          "fused mode: per-frame translation strength of the ICP refinement's prior where the view leaves the motion free");
    visit("fused_icp_prior_sigma_deg", fused_icp_prior_sigma_deg, 1e-3, 90.0, "deg",
          "fused mode: per-frame rotation strength of the ICP refinement's prior");
    visit("fused_max_noise_scale", fused_max_noise_scale, 0.1, 1000.0, "",
          "fused mode: a feature estimate whose inliers fit worse than this many times their noise is not the ICP's prior");
    visit("fused_min_geometric_thickness_m", fused_min_geometric_thickness_m, 0.0, 10.0, "m",
          "fused mode: geometric inliers must leave a plane by this much for their estimate to be the ICP's prior");
    visit("min_icp_inliers", min_icp_inliers, 3, 1000000, "",
          "an ICP-refined registration with fewer feature inliers than min_inliers needs this many point-to-plane inliers");
    visit("keyframe_capacity", keyframe_capacity, 2, 65536, "", "key-frames the back-end stores (about 1 MB each)");
    visit("keyframe_cloud_points", keyframe_cloud_points, 0, 1000000, "",
          "sampled points each key-frame keeps for ICP-refined loop closures (0: none)");
    visit("threads", threads, 1, 8, "", "threads sharing the per-frame loops, the tracking thread included");
    visit("loop_min_keyframe_gap", loop_min_keyframe_gap, 1, 10000, "",
          "the most recent key-frames are not loop-closure candidates");
    visit("loop_search_radius_m", loop_search_radius_m, 0.0, 100.0, "m", "loop-closure candidates lie this close");
    visit("loop_search_rotation_deg", loop_search_rotation_deg, 0.0, 180.0, "deg",
          "loop-closure candidates are turned at most this much from the new key-frame");
    visit("loop_drift_per_m", loop_drift_per_m, 0.0, 10.0, "",
          "translation drift allowed per metre travelled (widens the search and the consistency check)");
    visit("loop_drift_deg_per_m", loop_drift_deg_per_m, 0.0, 180.0, "deg/m", "rotation drift allowed per metre travelled");
    visit("loop_max_candidates", loop_max_candidates, 0, 100, "", "nearest candidates registered per key-frame (0: no loop closure)");
    visit("loop_candidates_per_frame", loop_candidates_per_frame, 0, 100, "",
          "loop-closure candidates registered per frame from the key-frame's own on (0: all in its frame)");
    visit("loop_initial_threshold", loop_initial_threshold, 0.0, 100000.0, "",
          "inliers (photometric + geometric) that close a loop until two closures set the adaptive threshold");
    visit("loop_threshold_deviations", loop_threshold_deviations, 0.0, 10.0, "",
          "T_epsilon: standard deviations below the mean inlier counts of past closures");
    visit("loop_max_correction_m", loop_max_correction_m, 0.0, 100.0, "m",
          "a closure may move the key-frame this much from the graph's estimate (plus drift allowance)");
    visit("loop_max_correction_deg", loop_max_correction_deg, 0.0, 180.0, "deg",
          "a closure may turn the key-frame this much from the graph's estimate (plus drift allowance)");
    visit("loop_min_inlier_spread_m", loop_min_inlier_spread_m, 0.0, 10.0, "m",
          "a closure's inliers must spread at least this far across their second axis");
    visit("loop_icp_above_rotation_sigma_deg", loop_icp_above_rotation_sigma_deg, 0.0, 180.0, "deg",
          "fused mode: a loop closure whose photometric inliers fix the rotation worse than this is refined by ICP (0: never for that)");
    visit("loop_icp_min_information_ratio", loop_icp_min_information_ratio, 0.0, 1.0e6, "",
          "fused mode: an ICP-refined loop closure is dropped where the surfaces fix some direction less than this fraction of the feature estimate");
    visit("graph_match_sigma_m", graph_match_sigma_m, 1e-6, 10.0, "m", "translation error of a registration on one match");
    visit("graph_match_sigma_deg", graph_match_sigma_deg, 1e-6, 180.0, "deg", "rotation error of a registration on one match");
    visit("graph_icp_sigma_m", graph_icp_sigma_m, 1e-5, 10.0, "m",
          "error of an ICP-refined registration along a direction its surfaces fully constrain (graph edge weight)");
    visit("graph_wheel_floor_m", graph_wheel_floor_m, 0.0, 10.0, "m",
          "translation noise added to a wheel edge between key-frames (0: no wheel edges)");
    visit("graph_wheel_floor_deg", graph_wheel_floor_deg, 1e-6, 180.0, "deg", "rotation noise added to a wheel edge between key-frames");
    visit("graph_planar_sigma_m", graph_planar_sigma_m, 0.0, 10.0, "m",
          "differential-drive base: height change between key-frames (0: no planar edges)");
    visit("graph_planar_sigma_deg", graph_planar_sigma_deg, 0.0, 90.0, "deg",
          "differential-drive base: roll and pitch change between key-frames (0: no planar edges)");
    visit("graph_iterations", graph_iterations, 1, 1000, "", "Levenberg-Marquardt iterations per pose-graph optimisation");
    visit("seed", seed, 0, 2147483647, "", "random seed: equal seeds give equal results");
  }
};

}  // namespace rankslam::slam
