#pragma once

#include "rankslam/dense/aligner.hpp"
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

/// The mode named `text` ("baseline", "photometric", "geometric", "fused"); nullopt for anything
/// else.
[[nodiscard]] constexpr std::optional<Mode> parse_mode(std::string_view text) {
  for (const Mode mode : {Mode::kBaseline, Mode::kPhotometric, Mode::kGeometric, Mode::kFused}) {
    if (text == to_string(mode)) return mode;
  }
  return std::nullopt;
}

/// Which ORB implementation extracts the photometric features.
enum class OrbImplementation : std::uint8_t {
  kFixedMemory,  ///< rankslam's OrbExtractor: memory fixed at set-up, nothing allocated per frame.
  kOpenCv,       ///< OpenCV's cv::ORB, which allocates on every frame: the measured reference.
};

/// Fused registration (docs/methods.md §6): the kinds' weights and when the geometric ICP refines.
/// Keys `slam.fused_*`.
struct FusedConfig {
  // Fused mode (docs/methods.md §6): a geometric keypoint is a voxel centroid, which moves by up
  // to a leaf between frames; with less noise its matches outweigh ORB's (docs/results.md §5).
  double geometric_leaf_sigma = 2.0;
  // Fewer photometric inliers call for the geometric ICP (coarse and fine; 0: never): it holds
  // plain surfaces but hurts on a cluttered Kinect desk, hence a low bound (docs/results.md §5).
  int icp_below_photometric_inliers = 30;
  // The ICP also refines where the photometric inliers fix the rotation worse than this (1 sigma):
  // corners on one distant poster fix tilt and height only together (docs/results.md §5). 0: never.
  double icp_above_rotation_sigma_deg = 1.0;
  // The ICP prior where the view leaves the motion free (docs/methods.md §6). 1: on a differential-
  // drive base, its drivable step with the feature estimate; 0: that estimate or the previous pose.
  int icp_base_kinematics = 1;
  // The ICP prior's strength per frame on the step from its pose: 5 mm holds the travel along a
  // plain corridor better than 1 or 3 cm (docs/results.md §1.3, §5).
  double icp_prior_sigma_m = 0.005;
  double icp_prior_sigma_deg = 1.0;
  // A feature estimate is the ICP's prior only if its inliers fit within this multiple of their
  // predicted noise: a dozen matches of noise fit far worse (docs/results.md §5).
  double max_noise_scale = 2.0;
  // Without min_inliers photometric inliers, the estimate's geometric inliers must also leave a
  // plane by this much: on one plane every SHOT descriptor looks alike (docs/results.md §5).
  double min_geometric_thickness_m = 0.1;
  // 1: each kind weighted by its inlier ratio against the other's (the thesis' W_P, W_G); 0: equal
  // weights, the comparison of the thesis' Table 5.4.
  int inlier_ratio_weights = 1;

  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("fused_geometric_leaf_sigma", geometric_leaf_sigma, 0.0, 10.0, "leaf",
          "fused mode: position noise of a geometric keypoint added per frame, in voxel leaves");
    visit("fused_icp_below_photometric_inliers", icp_below_photometric_inliers, 0, 100000, "",
          "fused mode: fewer photometric inliers than this call for the geometric ICP refinement (0: never)");
    visit("fused_icp_above_rotation_sigma_deg", icp_above_rotation_sigma_deg, 0.0, 180.0, "deg",
          "fused mode: photometric inliers that fix the rotation worse than this also call for the ICP refinement (0: never)");
    visit("fused_icp_base_kinematics", icp_base_kinematics, 0, 1, "",
          "fused mode on a differential-drive robot: the ICP prior is the base's drivable step with the feature estimate");
    visit("fused_icp_prior_sigma_m", icp_prior_sigma_m, 1e-4, 10.0, "m",
          "fused mode: per-frame translation strength of the ICP refinement's prior where the view leaves the motion free");
    visit("fused_icp_prior_sigma_deg", icp_prior_sigma_deg, 1e-3, 90.0, "deg",
          "fused mode: per-frame rotation strength of the ICP refinement's prior");
    visit("fused_max_noise_scale", max_noise_scale, 0.1, 1000.0, "",
          "fused mode: a feature estimate whose inliers fit worse than this many times their noise is not the ICP's prior");
    visit("fused_min_geometric_thickness_m", min_geometric_thickness_m, 0.0, 10.0, "m",
          "fused mode: geometric inliers must leave a plane by this much for their estimate to be the ICP's prior");
    visit("fused_inlier_ratio_weights", inlier_ratio_weights, 0, 1, "",
          "fused mode: 1 weights each kind by its inlier ratio against the other's; 0: equal weights");
  }
};

/// The coloured point map. Keys `slam.map_*`.
struct MapConfig {
  double voxel_m = 0.02;
  /// 0: room for every stored key-frame's points (MapBuilder::capacity).
  int max_points = 0;
  int points_per_keyframe = 5000;

  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("map_voxel_m", voxel_m, 0.001, 1.0, "m", "map voxel edge; points in one voxel are merged");
    visit("map_max_points", max_points, 0, 50'000'000, "",
          "capacity of the map (about 43 bytes a point, allocated at start); 0: keyframe_capacity x map_points_per_keyframe");
    visit("map_points_per_keyframe", points_per_keyframe, 100, 307200, "", "points sampled per key-frame");
  }
};

/// Local mapping (docs/methods.md §18): at each key-frame, a bundle adjustment of the newest
/// key-frames and the ORB landmarks they share, on the mapping thread; it refines the
/// registration edges between them. Keys `slam.local_*`.
struct LocalMapConfig {
  /// Key-frames adjusted together (below 2: no local mapping).
  int window = 5;
  int iterations = 10;
  /// Huber threshold on an observation's error in its own standard deviations (√χ²₃ at 95 %).
  double huber = 2.8;
  /// Besides the two points' own noise, how far (in pixels at the point's depth) a match may lie
  /// from where the key-frames' poses put it: the drift the window may hold.
  double match_radius_px = 15.0;

  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("local_window", window, 0, 16, "", "key-frames in the local bundle adjustment (below 2: off)");
    visit("local_iterations", iterations, 1, 100, "", "Levenberg-Marquardt iterations per local bundle adjustment");
    visit("local_huber", huber, 0.1, 100.0, "sigma", "Huber threshold of a landmark observation's error");
    visit("local_match_radius_px", match_radius_px, 0.0, 200.0, "px",
          "distance beyond the points' noise at which key-frame features still match as one landmark");
  }
};

/// Loop closure (docs/methods.md §10): the candidates, the adaptive threshold and the checks
/// against false closures. Keys `slam.loop_*`.
struct LoopConfig {
  // Loop-closure candidates: key-frames but the newest loop_min_keyframe_gap, within the radius and
  // rotation widened by the drift allowed since; the loop_max_candidates nearest are registered.
  int min_keyframe_gap = 5;
  double search_radius_m = 0.5;
  double search_rotation_deg = 30.0;
  double drift_per_m = 0.1;
  double drift_deg_per_m = 3.0;
  int max_candidates = 3;
  // Candidates registered per frame from the key-frame's on (0: all in its frame): spreading them
  // lowers the longest frames and raises the median (docs/results.md §2.2).
  int candidates_per_frame = 0;
  // Adaptive threshold ε on k_P + k_G (docs/methods.md §10): initial value until two closures exist
  // (lean low: the thesis saw 68-207), and T_ε.
  double initial_threshold = 60.0;
  double threshold_deviations = 1.0;
  // 0: the initial threshold throughout, the fixed threshold the thesis compares against (its Table 5.6).
  int adaptive_threshold = 1;
  // Against false closures: the registered pose may differ from the graph's by at most this plus
  // the drift allowance, and the inliers must spread this far (no line or blob).
  double max_correction_m = 0.1;
  double max_correction_deg = 5.0;
  double min_inlier_spread_m = 0.05;
  // A closure corrects the whole chain since its key-frame, so the ICP refines it already where its
  // photometric inliers fix the rotation worse than this (docs/results.md §5). 0: by inlier count.
  double icp_above_rotation_sigma_deg = 0.5;
  // A refined closure is taken only where the surfaces fix every direction this fraction as well as
  // the feature estimate: a blank wall or the floor alone fixes too little (docs/results.md §5).
  double icp_min_information_ratio = 0.1;
  // A closure must agree with the chain around its stored key-frame: where the stored one's
  // neighbours register the new key-frame, one must place it within this of the closure's pose,
  // or the closure is dropped (docs/methods.md §10). 0 m: no check.
  double neighbour_agreement_m = 0.02;
  double neighbour_agreement_deg = 2.0;

  /// Whether a correction of a pose `travelled_m` along the path from its reference is within the
  /// drift a loop closure may correct: max_correction_* plus drift_* per metre.
  [[nodiscard]] bool within_drift(double translation_m, double rotation_deg, double travelled_m) const {
    return translation_m <= max_correction_m + drift_per_m * travelled_m &&
           rotation_deg <= max_correction_deg + drift_deg_per_m * travelled_m;
  }

  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("loop_min_keyframe_gap", min_keyframe_gap, 1, 10000, "",
          "the most recent key-frames are not loop-closure candidates");
    visit("loop_search_radius_m", search_radius_m, 0.0, 100.0, "m", "loop-closure candidates lie this close");
    visit("loop_search_rotation_deg", search_rotation_deg, 0.0, 180.0, "deg",
          "loop-closure candidates are turned at most this much from the new key-frame");
    visit("loop_drift_per_m", drift_per_m, 0.0, 10.0, "",
          "translation drift allowed per metre travelled (widens the search and the consistency check)");
    visit("loop_drift_deg_per_m", drift_deg_per_m, 0.0, 180.0, "deg/m", "rotation drift allowed per metre travelled");
    visit("loop_max_candidates", max_candidates, 0, 100, "", "nearest candidates registered per key-frame (0: no loop closure)");
    visit("loop_candidates_per_frame", candidates_per_frame, 0, 100, "",
          "loop-closure candidates registered per frame from the key-frame's own on (0: all in its frame)");
    visit("loop_initial_threshold", initial_threshold, 0.0, 100000.0, "",
          "inliers (photometric + geometric) that close a loop until two closures set the adaptive threshold");
    visit("loop_threshold_deviations", threshold_deviations, 0.0, 10.0, "",
          "T_epsilon: standard deviations below the mean inlier counts of past closures");
    visit("loop_adaptive_threshold", adaptive_threshold, 0, 1, "",
          "1: the threshold adapts to past closures; 0: loop_initial_threshold throughout");
    visit("loop_max_correction_m", max_correction_m, 0.0, 100.0, "m",
          "a closure may move the key-frame this much from the graph's estimate (plus drift allowance)");
    visit("loop_max_correction_deg", max_correction_deg, 0.0, 180.0, "deg",
          "a closure may turn the key-frame this much from the graph's estimate (plus drift allowance)");
    visit("loop_min_inlier_spread_m", min_inlier_spread_m, 0.0, 10.0, "m",
          "a closure's inliers must spread at least this far across their second axis");
    visit("loop_icp_above_rotation_sigma_deg", icp_above_rotation_sigma_deg, 0.0, 180.0, "deg",
          "fused mode: a loop closure whose photometric inliers fix the rotation worse than this is refined by ICP (0: never for that)");
    visit("loop_icp_min_information_ratio", icp_min_information_ratio, 0.0, 1.0e6, "",
          "fused mode: an ICP-refined loop closure is dropped where the surfaces fix some direction less than this fraction of the feature estimate");
    visit("loop_neighbour_agreement_m", neighbour_agreement_m, 0.0, 10.0, "m",
          "a closure is dropped where neighbours of its stored key-frame register the new one and none places it this close; one below the adaptive threshold needs a neighbour that does (0: no check, the threshold alone)");
    visit("loop_neighbour_agreement_deg", neighbour_agreement_deg, 0.0, 180.0, "deg",
          "a closure is dropped where neighbours of its stored key-frame register the new one and none turns it this little from the closure");
  }
};

/// The wide-angle camera's part (docs/methods.md §14): at each key-frame, the first paired image
/// of a frame tracked from it is registered to stored key-frames; edges that fit the chain as a
/// loop closure must (loop_max_correction_* and loop_drift_*) join the pose graph. Keys `slam.wide_*`.
struct WideConfig {
  // Candidates per image: the nearest stored key-frames among the recent ones (older than the
  // previous key-frame, newer than loop_min_keyframe_gap) and among the older ones, and of the
  // other older ones those whose VLAD is most similar to one of the image's virtual views'; all 0: the
  // wide-angle camera's images are not used. Off by default: on the corridor loop the edges
  // helped no seed beyond a few per cent and cost accuracy with wheels (docs/results.md §10.4);
  // 2 and 2 is what was measured.
  int recent_candidates = 0;
  int loop_candidates = 0;
  int place_candidates = 0;
  // Candidates lie this close to the image's camera (plus the drift allowance) and look at most
  // this far from its direction.
  double search_radius_m = 3.0;
  double search_rotation_deg = 90.0;
  // A registration must have this many inliers and fix its translation this well (metres, along
  // its least certain direction; docs/results.md §10.2).
  int min_inliers = 12;
  double max_position_sigma_m = 0.03;

  [[nodiscard]] bool enabled() const { return recent_candidates + loop_candidates + place_candidates > 0; }

  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("wide_recent_candidates", recent_candidates, 0, 4, "",
          "recent stored key-frames (not the previous one, newer than loop_min_keyframe_gap) each wide-angle image is registered to");
    visit("wide_loop_candidates", loop_candidates, 0, 4, "",
          "older stored key-frames each wide-angle image is registered to, the nearest");
    visit("wide_place_candidates", place_candidates, 0, 4, "",
          "more older stored key-frames each wide-angle image is registered to, the most similar by VLAD (all three 0: the wide-angle camera is not used)");
    visit("wide_search_radius_m", search_radius_m, 0.0, 100.0, "m",
          "wide-angle candidates lie this close to the image's camera, plus the drift allowance");
    visit("wide_search_rotation_deg", search_rotation_deg, 0.0, 180.0, "deg",
          "wide-angle candidates look at most this far from the wide-angle camera's direction");
    visit("wide_min_inliers", min_inliers, 6, 10000, "", "fewest inliers of an RGB-D-to-wide-angle registration");
    visit("wide_max_position_sigma_m", max_position_sigma_m, 0.0, 10.0, "m",
          "largest standard deviation of an RGB-D-to-wide-angle registration's translation");
  }
};

/// Relocalisation (docs/methods.md §13): finding the camera in the stored key-frames after
/// tracking was lost or in a loaded map. Keys `slam.relocalise_*`.
struct RelocalisationConfig {
  // Failed registrations in a row that start a search of the whole map: a kidnapped robot fails
  // once and then tracks on from the wrong pose, so one is enough. 0: never (neither after a drop
  // of image inliers).
  int after_failed_frames = 1;
  // Stored key-frames the frame is registered with per frame while searching: bounds a searching
  // frame's cost (about 2 ms each); the whole store takes key-frames / this many frames.
  int keyframes_per_frame = 8;
  // Consecutive frames whose relocalisations must agree (within max_deviation_*) before the
  // pose is taken: one registration against a repeated texture can pass every other check.
  int confirm_frames = 2;

  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("relocalise_after_failed_frames", after_failed_frames, 0, 1000, "",
          "failed registrations in a row that start a search of the whole map (0: never)");
    visit("relocalise_keyframes_per_frame", keyframes_per_frame, 1, 65536, "",
          "stored key-frames registered per frame while searching");
    visit("relocalise_confirm_frames", confirm_frames, 1, 100, "",
          "consecutive frames whose relocalisations must agree before the pose is taken");
  }
};

/// The pose graph (docs/methods.md §8, §11): edge weights and the optimiser. Keys `slam.graph_*`.
struct GraphConfig {
  // Error of a registration on one well-fitting match (graph::information_from_matches); a worse
  // fit divides the information by its noise scale squared (Backend::registration_information).
  double match_sigma_m = 0.02;
  double match_sigma_deg = 1.0;
  // ICP-refined key-frame edges add the surfaces' information at this error per fully constraining
  // direction, so a loop closure bends the chain where the view left the motion free.
  double icp_sigma_m = 0.005;
  int iterations = 20;
  // Wheel edges between key-frames: the wheel motion plus this floor per axis (0 m: none), kept
  // below the wheels' own noise over a key-frame step (5 mm) not to bury it (docs/results.md §5).
  double wheel_floor_m = 0.001;
  double wheel_floor_deg = 0.05;
  // Differential-drive base: key-frame edges hold height, roll and pitch, which vision lets drift
  // and a closure would spread over the loop (docs/results.md §1.3, §5). 0: no such edges.
  double planar_sigma_m = 0.005;
  double planar_sigma_deg = 0.2;

  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("graph_match_sigma_m", match_sigma_m, 1e-6, 10.0, "m", "translation error of a registration on one match");
    visit("graph_match_sigma_deg", match_sigma_deg, 1e-6, 180.0, "deg", "rotation error of a registration on one match");
    visit("graph_icp_sigma_m", icp_sigma_m, 1e-5, 10.0, "m",
          "error of an ICP-refined registration along a direction its surfaces fully constrain (graph edge weight)");
    visit("graph_wheel_floor_m", wheel_floor_m, 0.0, 10.0, "m",
          "translation noise added to a wheel edge between key-frames (0: no wheel edges)");
    visit("graph_wheel_floor_deg", wheel_floor_deg, 1e-6, 180.0, "deg", "rotation noise added to a wheel edge between key-frames");
    visit("graph_planar_sigma_m", planar_sigma_m, 0.0, 10.0, "m",
          "differential-drive base: height change between key-frames (0: no planar edges)");
    visit("graph_planar_sigma_deg", planar_sigma_deg, 0.0, 90.0, "deg",
          "differential-drive base: roll and pitch change between key-frames (0: no planar edges)");
    visit("graph_iterations", iterations, 1, 1000, "", "Levenberg-Marquardt iterations per pose-graph optimisation");
  }
};

/// Parameters of the SLAM loop: a tree of the parts' own structs (fused registration, map, loop
/// closure, pose graph, wheel arbiter, geometric front-end) under the tracking and shared ones.
/// Each is declared once, in its struct's visit_parameters(), with its range, unit and meaning;
/// the configuration loader and the start-up printout both walk that list. `mode` is a named
/// choice, set apart from the numeric parameters.
struct SlamConfig {
  Mode mode = Mode::kBaseline;
  /// Not read from configuration files: OpenCV's ORB is kept for side-by-side measurements.
  OrbImplementation orb_implementation = OrbImplementation::kFixedMemory;

  int orb_features = 1000;
  double orb_scale_factor = 1.2;
  int orb_levels = 8;
  int orb_fast_threshold = 20;
  /// 1: the photometric features' keypoints are ROS2D's residual peaks (docs/methods.md §15), the
  /// strongest orb_features of them, described by the same steered BRIEF as ORB's own; 0: ORB's
  /// FAST corners. Off: better only on plain walls in photometric mode (docs/results.md §13).
  int ros2d_keypoints = 0;
  /// 1: each accepted feature registration is refined by dense photometric and depth alignment
  /// to the same target (docs/methods.md §17); the feature estimate stays where the refinement
  /// does not fit better or moves beyond dense_max_change_m. Off: 1.2–7× lower ATE on textured
  /// scenes but worse on plain zig-zag panels (docs/results.md §14), and 9–11 ms more per frame.
  int dense_refinement = 0;
  int dense_levels = 3;
  double dense_min_gradient = 6.0;
  double dense_depth_weight = 1.0;
  double dense_max_change_m = 0.03;
  int max_hamming_distance = 64;
  double min_depth_m = 0.3;
  double max_depth_m = 4.0;
  // A keypoint's depth error beyond the sensor's (calibration depth_noise_per_m): colour-depth
  // registration and timing errors at corners, which also grow with z^2; the two add to 5e-3 for
  // the Kinect (docs/results.md §5).
  double keypoint_depth_noise_per_m = 3.575e-3;
  double keypoint_sigma_px = 0.5;
  // Colour camera readout time: under fast rotation keypoints move to the frame's mid-exposure
  // pose; 15 ms fits fr1's Kinect, 0 a global shutter (docs/results.md §5).
  double rolling_shutter_readout_ms = 15.0;
  double ransac_threshold_m = 0.02;
  int ransac_iterations = 1000;
  int msse_hypotheses = 1000;
  // MSSE kappa: 0.1 lets the fit latch onto small subsets that fit too well (one plane's identical
  // quantised depths); 0.3 stays below the true inlier fractions seen (docs/results.md §5).
  double msse_min_inlier_fraction = 0.3;
  // MSSE re-segment-and-refit rounds after the first refit: the thesis refits once (0); more rounds
  // shrink the inlier set towards its tightest core on real data (docs/results.md §5).
  int msse_refine_iterations = 0;
  int min_inliers = 12;
  double max_step_translation_m = 0.5;
  double max_step_rotation_deg = 45.0;
  double max_deviation_translation_m = 0.1;
  double max_deviation_rotation_deg = 10.0;
  // Failed frames in a row that extrapolate at constant velocity (half a second at 30 Hz bridges a
  // blur or an occluder); later ones hold the pose, so a stopped robot is not carried off.
  int max_extrapolated_frames = 15;
  // Frame-to-key-frame tracking (see SlamLoop): a frame below this overlap becomes the reference;
  // 0.5 was the most accurate of the values tried (docs/results.md §5).
  double reference_min_overlap = 0.5;
  // A reference registration with a larger noise scale also tries the previous frame and keeps
  // the better fit: the inlier count alone holds on to a lost reference (docs/results.md §5).
  double reference_max_noise_scale = 2.0;
  double keyframe_translation_m = 0.25;
  double keyframe_rotation_deg = 15.0;
  // Dark scenes (docs/methods.md §2): 30 lies well between lit rooms' mean grey level and a dark
  // room's sensor noise; the IR image's low contrast needs a FAST threshold of its own.
  double ir_switch_brightness = 30.0;
  int ir_orb_fast_threshold = 8;
  /// The wheel/vision arbiter (SlamLoop::process with a MotionPrior).
  nav::WheelArbiterConfig wheels;
  // An ICP-refined registration below min_inliers feature inliers needs this many point-to-plane
  // inliers: a lone wall at 1 m gives thousands (docs/results.md §5).
  int min_icp_inliers = 300;
  // Back-end (docs/methods.md §8, §10–§11): key-frame store, loop closure, pose graph.
  // Stored key-frames, about 0.5 MB each; when full, one far from the camera with the fewest loop
  // closures is retired (KeyframeStore::retirement_candidate).
  int keyframe_capacity = 128;
  // Points (about 36 bytes each) a key-frame keeps to ICP-refine closures on weak photometric
  // inliers; 0: those are not taken, so a plain corridor never closes (docs/results.md §5).
  int keyframe_cloud_points = 6000;
  // Threads sharing the per-frame loops, the tracking thread included: the robot computer's two
  // cores. The estimates are the same for any count.
  int threads = 2;
  FusedConfig fused;
  MapConfig map;
  LocalMapConfig local;
  LoopConfig loop;
  WideConfig wide;
  RelocalisationConfig relocalisation;
  GraphConfig graph;
  int seed = 1;

  /// The depth-only front-end of the geometric and fused modes (docs/methods.md §3–§5); its own
  /// parameter list, without the depth range, MSSE hypotheses and seed every part shares.
  geometry::GeometryConfig geometry;

  /// The dense refinement's options: the dense_* parameters with the loop's depth range and the
  /// sensor's axial noise `depth_noise_per_m` (calibration).
  [[nodiscard]] dense::DenseOptions dense_options(double depth_noise_per_m) const {
    dense::DenseOptions options;
    options.levels = dense_levels;
    options.min_gradient = dense_min_gradient;
    options.depth_weight = dense_depth_weight;
    options.max_change_m = dense_max_change_m;
    options.min_depth_m = min_depth_m;
    options.max_depth_m = max_depth_m;
    options.depth_noise_per_m = depth_noise_per_m;
    return options;
  }

  /// The geometric front-end's configuration: `geometry` with the loop's depth range, MSSE
  /// hypotheses and seed.
  [[nodiscard]] geometry::GeometryConfig geometric_frontend() const {
    geometry::GeometryConfig frontend = geometry;
    frontend.min_depth_m = min_depth_m;
    frontend.max_depth_m = max_depth_m;
    frontend.msse_hypotheses = msse_hypotheses;
    frontend.seed = seed;
    return frontend;
  }

  /// Calls visit(name, field, min, max, unit, doc) for every numeric parameter.
  template <typename Visitor>
  void visit_parameters(Visitor&& visit) {
    visit("orb_features", orb_features, 100, 20000, "", "ORB keypoints detected per frame");
    visit("orb_scale_factor", orb_scale_factor, 1.05, 2.0, "", "ORB pyramid scale between levels");
    visit("orb_levels", orb_levels, 1, 16, "", "ORB pyramid levels");
    visit("orb_fast_threshold", orb_fast_threshold, 1, 100, "", "FAST corner threshold");
    visit("ros2d_keypoints", ros2d_keypoints, 0, 1, "",
          "1: ROS2D keypoints (ch. 7) described by ORB's steered BRIEF instead of FAST corners");
    visit("dense_refinement", dense_refinement, 0, 1, "", "1: dense photometric + depth refinement of each registration");
    visit("dense_levels", dense_levels, 1, 5, "", "pyramid levels of the dense refinement");
    visit("dense_min_gradient", dense_min_gradient, 0.0, 255.0, "grey/px",
          "grey gradient from which a pixel joins the dense photometric term");
    visit("dense_depth_weight", dense_depth_weight, 0.0, 10.0, "", "weight of the dense depth term (0: grey only)");
    visit("dense_max_change_m", dense_max_change_m, 0.001, 1.0, "m",
          "largest change the dense refinement may make to a registration");
    visit("max_hamming_distance", max_hamming_distance, 1, 256, "bit", "largest descriptor distance of a match");
    visit("min_depth_m", min_depth_m, 0.0, 10.0, "m", "nearest depth any part uses");
    visit("max_depth_m", max_depth_m, 0.1, 20.0, "m", "farthest depth any part uses (features, ICP, map)");
    visit("keypoint_depth_noise_per_m", keypoint_depth_noise_per_m, 0.0, 0.1, "1/m",
          "b in a keypoint's depth error (a+b)*z^2 on top of the sensor's a (calibration depth_noise_per_m)");
    visit("keypoint_sigma_px", keypoint_sigma_px, 0.01, 10.0, "px",
          "keypoint localisation error at the finest pyramid level");
    visit("rolling_shutter_readout_ms", rolling_shutter_readout_ms, 0.0, 100.0, "ms",
          "colour camera readout time, top to bottom row (0: global shutter)");
    visit("ransac_threshold_m", ransac_threshold_m, 0.001, 1.0, "m", "baseline RANSAC inlier threshold");
    visit("ransac_iterations", ransac_iterations, 10, 100000, "", "baseline RANSAC hypotheses");
    visit("msse_hypotheses", msse_hypotheses, 10, 100000, "", "MSSE minimal-sample hypotheses per registration (both feature kinds)");
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
    visit("ir_switch_brightness", ir_switch_brightness, 0.0, 255.0, "level",
          "mean grey level of the colour image below which features come from the IR image (0: never)");
    visit("ir_orb_fast_threshold", ir_orb_fast_threshold, 1, 100, "", "FAST corner threshold on the IR image");
    wheels.visit_parameters(visit);
    visit("min_icp_inliers", min_icp_inliers, 3, 1000000, "",
          "an ICP-refined registration with fewer feature inliers than min_inliers needs this many point-to-plane inliers");
    visit("keyframe_capacity", keyframe_capacity, 2, 65536, "", "key-frames the back-end stores (about 0.5 MB each)");
    visit("keyframe_cloud_points", keyframe_cloud_points, 0, 1000000, "",
          "sampled points each key-frame keeps for ICP-refined loop closures (0: none)");
    visit("threads", threads, 1, 8, "", "threads sharing the per-frame loops, the tracking thread included");
    fused.visit_parameters(visit);
    map.visit_parameters(visit);
    local.visit_parameters(visit);
    loop.visit_parameters(visit);
    wide.visit_parameters(visit);
    relocalisation.visit_parameters(visit);
    graph.visit_parameters(visit);
    visit("seed", seed, 0, 2147483647, "", "random seed: equal seeds give equal results");
  }
};

}  // namespace rankslam::slam
