#pragma once

// Parameters of the geometric front-end (docs/methods.md §3–§5; Yousif 2016 ch. 4–5). Thesis values
// are the defaults where the thesis gives one; every other default is ours and says so.

#include <cstdint>
#include <string_view>

namespace rankslam::geometry {

/// Which sampled points become keypoints.
enum class KeypointMethod : std::uint8_t {
  kIs3d,     ///< Informatively sampled 3D features: points in no dominant orientation (ch. 5).
  kRos,      ///< Rank-order-statistics keypoints: salient local normal variation (ch. 4).
  kUniform,  ///< Uniform sampling to about max_keypoints points (the thesis' baseline).
};

[[nodiscard]] constexpr std::string_view to_string(KeypointMethod method) {
  switch (method) {
    case KeypointMethod::kIs3d: return "is3d";
    case KeypointMethod::kRos: return "ros";
    case KeypointMethod::kUniform: return "uniform";
  }
  return "unknown";
}

/// How the IS3D features are ranked when more than max_keypoints remain outside every dominant
/// orientation group (the thesis keeps "about 400" and does not say which).
enum class Is3dRanking : std::uint8_t {
  /// Largest local saliency first (ROS's θ_i, the mean squared normal angle to the nearest
  /// sampled neighbours), after dropping the top gross-error fraction like ROS: the sharpest
  /// creases and corners among the points no large plane claims. The most repeatable of the
  /// three on every pair set of test/bench/geometry's repeatability tool.
  kLocalSaliency,
  /// Largest angle to the nearest dominant orientation first, after dropping the top gross-error
  /// fraction.
  kFarthestFromOrientations,
  /// Smallest angle to the nearest dominant orientation first, as ROS takes the first values
  /// past its transition point.
  kNearestToOrientations,
};

/// Which points of ROS's group 2 (past MSSE's transition, its largest gross_error_fraction
/// dropped) become the max_keypoints keypoints.
enum class RosSelection : std::uint8_t {
  /// The most salient (largest θ) first. Ours: the first values past the transition lie at crease
  /// fringes, where the transition moves with the noise (repeatability: docs/results.md §5).
  kMostSalient,
  /// The first values past the transition, in ascending θ (thesis §4.3.3: "the first 400 sorted
  /// values of GROUP 2").
  kFirstPastTransition,
};

[[nodiscard]] constexpr std::string_view to_string(RosSelection selection) {
  switch (selection) {
    case RosSelection::kMostSalient: return "most-salient";
    case RosSelection::kFirstPastTransition: return "first-past-transition";
  }
  return "unknown";
}

/// Parameters of GeometricFrontend. Each numeric field is declared once more in
/// visit_parameters() with its range, unit and meaning, for the configuration loader and the
/// start-up printout. Immutable once a front-end is configured with it.
struct GeometryConfig {
  /// Keypoint detector. Not in visit_parameters() (not numeric); the loader maps its name
  /// (to_string) itself.
  KeypointMethod keypoint_method = KeypointMethod::kIs3d;
  /// IS3D ranking; see Is3dRanking. Not in visit_parameters() for the same reason.
  Is3dRanking is3d_ranking = Is3dRanking::kLocalSaliency;
  /// ROS selection; see RosSelection. Not in visit_parameters() for the same reason.
  RosSelection ros_selection = RosSelection::kMostSalient;

  // --- Pre-processing (§3.1–3.3) ---------------------------------------------------------------
  /// Pass-through: points farther than this are dropped, nearer than min_depth_m too. In the SLAM
  /// loop these, msse_hypotheses and seed are the loop's own (SlamConfig::geometric_frontend).
  double max_depth_m = 4.0;
  double min_depth_m = 0.0;
  /// Pixel stride of the cloud-resolution estimate φ (mean distance to the nearest of 8 image
  /// neighbours). Ours: 4 measures close to the full cloud's mean (docs/results.md §5).
  int resolution_pixel_stride = 4;
  /// C in the adaptive voxel leaf ρ = C·φ (thesis eq. 4.5: 11 → about 4 000 points).
  double voxel_leaf_factor = 11.0;
  /// Bounds of ρ, so that a degenerate frame (all far, all near) cannot blow up the cloud.
  double min_voxel_leaf_m = 0.005;
  double max_voxel_leaf_m = 0.25;
  /// Normal support radius in ρ: "intentionally large" so normals bend near edges (thesis §4.4.2,
  /// no number); ours, 1.5ρ (≈ 5 cm at 1.5 m), by keypoint repeatability and registration accuracy.
  double normal_radius_factor = 1.5;
  /// Dense neighbours sampled per axis of the normal's pixel window (the window spans the
  /// support radius at the point's depth; the stride is chosen to give about this many).
  int normal_samples_per_axis = 12;
  /// A sampled point whose normal has fewer dense neighbours is dropped.
  int normal_min_neighbours = 8;

  // --- Keypoints (§3.4, §4) -------------------------------------------------------------------
  /// Keypoints kept per frame (thesis: about 400 for ROS and IS3D).
  int max_keypoints = 400;
  /// ROS: N nearest sampled neighbours whose normal angles give θ_i (thesis eq. 4.2; N is not
  /// stated there; ours: 10).
  int ros_neighbours = 10;
  /// ROS: κ of the MSSE segmentation of θ (thesis §4.3.3: 20 %).
  double ros_min_inlier_fraction = 0.2;
  /// ROS: fraction of group 2's largest saliency values dropped as gross sensor errors (thesis
  /// §4.3.3: "e.g. last 5 %"). IS3D has its own, is3d_gross_error_fraction.
  double gross_error_fraction = 0.05;
  /// IS3D: random normals tried per round as dominant orientations (n of thesis eq. 5.1, unstated;
  /// ours: 50 finds a group of ≥ 10 % of the points with probability 1 − 0.9⁵⁰ > 99 %).
  int is3d_hypotheses = 50;
  /// IS3D: κ of each least-k-th-order orientation fit, relative to the points still unassigned.
  double is3d_min_inlier_fraction = 0.2;
  /// IS3D: smallest share of all points a dominant group holds (ours: 20 %, as κ); smaller limits
  /// remove the creases' own groups of bent normals and lose repeatability (docs/results.md §5).
  double is3d_min_group_fraction = 0.2;
  /// IS3D: at most this many dominant orientations are removed.
  int is3d_max_orientations = 6;
  /// IS3D: largest RMS angle of a dominant group (ours): past the planes, MSSE's transition never
  /// fires and the next "orientation" would swallow every remaining point (docs/results.md §5).
  double is3d_max_group_scale_deg = 30.0;
  /// IS3D: top-ranked candidates dropped before max_keypoints are kept (ours: none, as the thesis'
  /// IS3D); a 5 % cut like ROS's drops the sharpest creases and corners (docs/results.md §5).
  double is3d_gross_error_fraction = 0.0;

  // --- SHOT (Tombari et al. 2010) --------------------------------------------------------------
  /// Support radius of the SHOT descriptor and its local reference frame, over the sampled cloud;
  /// fixed in metres (ours) so that descriptors of frames at different depths stay comparable.
  double shot_radius_m = 0.25;
  /// A keypoint with fewer support points (itself included) gets no descriptor (PCL: 5).
  int shot_min_neighbours = 5;

  // --- Registration (§1, §3.6–3.7) -------------------------------------------------------------
  /// MSSE hypotheses (thesis ch. 3: 1000 minimal samples).
  int msse_hypotheses = 1000;
  /// MSSE κ for the rigid fit over the mutual matches (see robust::MsseConfig).
  double msse_min_inlier_fraction = 0.1;
  /// 1: rank the MSSE residuals in units of each match's predicted noise (the calibration's
  /// σ_z = a·z²);
  /// 0: plain metres.
  int per_point_noise = 1;
  /// Lateral noise of one keypoint per axis; covers the voxel-centroid quantisation.
  double lateral_sigma_m = 0.003;
  /// A registration with fewer MSSE inliers is reported as failed.
  int min_inliers = 10;
  /// MSSE hypotheses farther from the motion guess are rejected (robust::RigidMotionGate; 0: no
  /// limit): motion at 30 Hz is far smaller, so repeated structure cannot win by a period's shift.
  double motion_gate_translation_m = 0.5;
  double motion_gate_rotation_deg = 45.0;

  // --- ICP refinement (docs/methods.md §7, on the sampled clouds) ----------------
  /// Coarse point-to-plane ICP iterations after MSSE (0: the thesis' MSSE only). Ours: centroid
  /// matches fix the motion to about a leaf; the ICP brings the drift down to the sensor noise.
  int icp_iterations = 8;
  /// Iterations of the fine stage: the current frame's dense block means against the previous
  /// frame's flattest centroids (see icp_fine_max_curvature and icp_fine_max_points).
  int icp_fine_iterations = 4;
  /// Current-frame sampled points used by coarse ICP at most (evenly strided).
  int icp_max_points = 1500;
  /// Fine stage: at most this many of the current frame's 4 × 4 pixel block means (evenly strided),
  /// which fix the rotation better than the sampled centroids (docs/results.md §5).
  int icp_fine_max_points = 5000;
  /// ICP associations farther than this many voxel leaves are not made.
  double icp_max_distance_factor = 3.0;
  /// MSSE κ of the ICP residual segmentation.
  double icp_min_inlier_fraction = 0.3;
  /// Coarse stage: only points of surface variation λ₀/Σλ below this; near edges the large normal
  /// support bends normals and moves centroids off the surfaces, biasing point-to-plane residuals.
  double icp_max_curvature = 0.02;
  /// Fine stage limit: only the flattest points, as the fine ICP's drift falls with this limit
  /// (docs/results.md §5).
  double icp_fine_max_curvature = 0.003;
  /// 1: unless MSSE's estimate is within 2 cm and 1° of the motion guess, the coarse stage also
  /// starts from the guess and the start with more close associations wins. 0: MSSE's only.
  int icp_guess_fallback = 1;
  /// IcpConfig::prior_crossover: a caller's prior holds a direction with weight τ/(τ+λ), λ the
  /// data's information there over the prior's. 0: the whole prior everywhere.
  double icp_prior_crossover = 1.0;
  /// ICP leaves out points deeper than max_depth_m less this many depth-noise σ (0: none): near the
  /// cut a surface keeps only its near-falling samples and comes out short (docs/results.md §1.3).
  double icp_pass_through_margin_sigmas = 2.0;

  /// Seed of the random choices (IS3D hypotheses, MSSE samples): equal seeds, equal results.
  int seed = 1;

  /// Calls visit(name, field, min, max, unit, doc) for every numeric parameter.
  template <class V>
  void visit_parameters(V&& visit) {
    visit("resolution_pixel_stride", resolution_pixel_stride, 1, 64, "px",
          "pixel stride of the cloud-resolution (mean nearest-neighbour distance) estimate");
    visit("voxel_leaf_factor", voxel_leaf_factor, 1.0, 100.0, "",
          "C in the adaptive voxel leaf rho = C * resolution (thesis: 11)");
    visit("min_voxel_leaf_m", min_voxel_leaf_m, 0.001, 1.0, "m", "smallest voxel leaf");
    visit("max_voxel_leaf_m", max_voxel_leaf_m, 0.001, 1.0, "m", "largest voxel leaf");
    visit("normal_radius_factor", normal_radius_factor, 0.25, 10.0, "",
          "normal support radius in voxel leaves (dense neighbours, deliberately large)");
    visit("normal_samples_per_axis", normal_samples_per_axis, 3, 64, "",
          "dense neighbours sampled per axis of a normal's pixel window");
    visit("normal_min_neighbours", normal_min_neighbours, 3, 10000, "",
          "fewest dense neighbours for a normal");
    visit("max_keypoints", max_keypoints, 3, 100000, "", "keypoints kept per frame (thesis: 400)");
    visit("ros_neighbours", ros_neighbours, 1, 64, "", "ROS: nearest sampled neighbours per point");
    visit("ros_min_inlier_fraction", ros_min_inlier_fraction, 0.01, 0.99, "",
          "ROS: MSSE kappa of the saliency segmentation (thesis: 0.2)");
    visit("gross_error_fraction", gross_error_fraction, 0.0, 0.5, "",
          "ROS: largest saliencies of group 2 dropped as gross sensor errors (thesis: 0.05)");
    visit("is3d_hypotheses", is3d_hypotheses, 1, 100000, "",
          "IS3D: normals tried as dominant-orientation hypotheses per round");
    visit("is3d_min_inlier_fraction", is3d_min_inlier_fraction, 0.01, 0.99, "",
          "IS3D: MSSE kappa of each orientation fit");
    visit("is3d_min_group_fraction", is3d_min_group_fraction, 0.001, 0.99, "",
          "IS3D: smallest share of all points a dominant orientation holds");
    visit("is3d_max_orientations", is3d_max_orientations, 1, 64, "",
          "IS3D: most dominant orientations removed");
    visit("is3d_max_group_scale_deg", is3d_max_group_scale_deg, 0.1, 90.0, "deg",
          "IS3D: largest angular noise scale of a dominant orientation group");
    visit("is3d_gross_error_fraction", is3d_gross_error_fraction, 0.0, 0.5, "",
          "IS3D: highest-ranked candidates dropped before the kept ones (thesis: none)");
    visit("shot_radius_m", shot_radius_m, 0.01, 2.0, "m", "SHOT support radius");
    visit("shot_min_neighbours", shot_min_neighbours, 2, 10000, "",
          "fewest support points of a SHOT descriptor");
    visit("msse_min_inlier_fraction", msse_min_inlier_fraction, 0.01, 0.9, "",
          "MSSE kappa: assumed least inlier fraction of the matches");
    visit("per_point_noise", per_point_noise, 0, 1, "",
          "rank MSSE residuals in units of each match's predicted noise");
    visit("lateral_sigma_m", lateral_sigma_m, 0.0, 1.0, "m", "lateral noise of a keypoint per axis");
    visit("min_inliers", min_inliers, 3, 100000, "", "fewer MSSE inliers mark a registration failed");
    visit("motion_gate_translation_m", motion_gate_translation_m, 0.0, 100.0, "m",
          "MSSE hypotheses farther from the motion guess are rejected (0: no limit)");
    visit("motion_gate_rotation_deg", motion_gate_rotation_deg, 0.0, 180.0, "deg",
          "MSSE hypotheses rotated farther from the motion guess are rejected (0: no limit)");
    visit("icp_iterations", icp_iterations, 0, 100, "", "coarse point-to-plane ICP iterations after MSSE (0: no ICP)");
    visit("icp_fine_iterations", icp_fine_iterations, 0, 100, "", "fine ICP iterations on the flattest points");
    visit("icp_max_points", icp_max_points, 12, 100000, "", "sampled points used by ICP at most");
    visit("icp_fine_max_points", icp_fine_max_points, 12, 100000, "", "sampled points used by fine ICP at most");
    visit("icp_max_distance_factor", icp_max_distance_factor, 0.5, 100.0, "",
          "ICP association distance in voxel leaves");
    visit("icp_min_inlier_fraction", icp_min_inlier_fraction, 0.01, 0.99, "",
          "MSSE kappa of the ICP residual segmentation");
    visit("icp_max_curvature", icp_max_curvature, 0.0, 1.0, "",
          "largest surface variation of a point in coarse ICP (0: no limit)");
    visit("icp_fine_max_curvature", icp_fine_max_curvature, 0.0, 1.0, "",
          "largest surface variation of a point in fine ICP (0: no limit)");
    visit("icp_guess_fallback", icp_guess_fallback, 0, 1, "",
          "also start ICP from the motion guess unless MSSE's estimate is close to it");
    visit("icp_prior_crossover", icp_prior_crossover, 0.0, 1e6, "",
          "data-to-prior information ratio at which an ICP prior's hold on a direction halves (0: whole prior)");
    visit("icp_pass_through_margin_sigmas", icp_pass_through_margin_sigmas, 0.0, 10.0, "",
          "ICP leaves out points within this many depth-noise sigmas of the pass-through (0: none)");
  }

  /// The depth beyond which the ICP takes no point: max_depth_m less the pass-through margin, for
  /// a sensor of axial noise depth_noise_per_m·z².
  [[nodiscard]] double icp_depth_limit_m(double depth_noise_per_m) const {
    return max_depth_m - icp_pass_through_margin_sigmas * depth_noise_per_m * max_depth_m * max_depth_m;
  }

  /// Empty when every field is in range and consistent, else the name of the first offending
  /// field.
  [[nodiscard]] std::string_view validate() const;
};

}  // namespace rankslam::geometry
