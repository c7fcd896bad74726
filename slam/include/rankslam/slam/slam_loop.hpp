#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/geometry/frontend.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/parallel/companion.hpp"
#include "rankslam/slam/camera.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/icp.hpp"
#include "rankslam/graph/background_optimizer.hpp"
#include "rankslam/graph/pose_graph.hpp"
#include "rankslam/slam/image_source.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/motion_estimator.hpp"
#include "rankslam/slam/orb_frontend.hpp"
#include "rankslam/slam/point_map.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <random>
#include <string_view>
#include <vector>

namespace rankslam::slam {

/// What the loop made of one frame.
enum class FrameStatus : std::uint8_t {
  kFirstFrame,  ///< Defines the world frame.
  kTracking,    ///< Registered against the tracking key-frame or, failing that, the previous frame.
  kFailed,      ///< Registration failed, no wheel prior: the pose was propagated at constant velocity.
  kWheels,      ///< Registration failed or was overruled: the pose follows the wheel odometry prior.
};

[[nodiscard]] constexpr std::string_view to_string(FrameStatus status) {
  switch (status) {
    case FrameStatus::kFirstFrame: return "first-frame";
    case FrameStatus::kTracking: return "tracking";
    case FrameStatus::kFailed: return "failed";
    case FrameStatus::kWheels: return "wheels";
  }
  return "unknown";
}

/// The camera's motion since the previous frame as the wheel odometry measured it: the prediction
/// for registration and the fallback when registration fails. See camera_motion_prior().
struct MotionPrior {
  /// The camera at this frame in the camera frame at the previous frame processed.
  Eigen::Isometry3d T_previous_current = Eigen::Isometry3d::Identity();
  /// Covariance of the motion: a small motion ξ = (rotation vector, translation) applied on the
  /// left, T_previous_current = exp(ξ)·mean, expressed in the previous camera frame.
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

/// The camera motion prior from a planar base motion (x, y, yaw of the base at the current frame
/// in the base frame at the previous one, with its 3×3 covariance in that frame) and the camera's
/// mounting T_base_cam: T_cam_prev_cam_cur = T_cam_base · T_base_prev_base_cur · T_base_cam, the
/// covariance propagated to first order.
[[nodiscard]] MotionPrior camera_motion_prior(double x_m, double y_m, double yaw_rad,
                                              const Eigen::Matrix3d& planar_covariance,
                                              const Eigen::Isometry3d& T_base_cam);

/// How vision and the wheel prior related on one frame (all false/0 without a prior).
struct WheelCheck {
  bool prior_given = false;
  /// A registration was accepted and compared with the prior.
  bool compared = false;
  /// Squared Mahalanobis distance of the registered motion from the prior, this frame alone and
  /// summed over the last wheel_gate_window_frames compared frames.
  double frame_distance_sq = 0.0;
  double window_distance_sq = 0.0;
  /// The registered motion less the wheels', in the base frame at the previous frame: along
  /// the drive direction, across it, and about the vertical (what the wheels measure), then
  /// height, roll and pitch (what a planar base cannot make).
  double forward_residual_m = 0.0;
  double lateral_residual_m = 0.0;
  double yaw_residual_deg = 0.0;
  double height_residual_m = 0.0;
  double tilt_residual_deg = 0.0;
  /// Either distance beyond wheel_gate_chi2.
  bool disagree = false;
  /// The residual is what one slipping wheel leaves: a heading residual of wheel_slip_yaw_deg or
  /// more, and across the drive direction, in height and in tilt no more than the vision noise.
  bool slip_shaped = false;
  /// They agreed: the pose is the covariance-weighted combination of the registration and the prior.
  bool fused = false;
  /// Vision won: slip-shaped residuals for wheel_slip_min_frames in a row, a heading residual
  /// turning one way for wheel_slip_heading_frames, or a strong registration
  /// (wheel_strong_inliers) disagreeing otherwise, as the base can move, for
  /// wheel_override_min_frames; and for as long as the disagreement then lasts.
  bool vision_trusted = false;
  /// Wheels won: a registration disagreed and was replaced by the prior (status kWheels).
  bool wheels_trusted = false;
  /// Frames in a row of the current kind of disagreement: slip-shaped, or strong and otherwise
  /// disagreeing.
  int disagree_in_a_row = 0;
  /// This frame started a disagreement that vision won (counted in
  /// SlamLoop::wheel_slip_events()).
  bool slip_event = false;
};

/// Per-stage wall time of one frame, milliseconds.
struct StageTimes {
  static constexpr std::size_t kCount = 6;
  static constexpr std::array<std::string_view, kCount> kNames = {"preprocess", "features", "matching",
                                                                   "estimation", "icp",      "mapping"};
  std::array<double, kCount> ms{};
};

struct FrameResult {
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  FrameStatus status = FrameStatus::kFirstFrame;
  /// Why the frame failed; empty when it did not.
  std::string_view failure_reason;
  /// The image the features came from: infrared when the colour image was dark or absent.
  ImageSource image_source = ImageSource::kColour;
  int features = 0;
  int matches = 0;
  int inliers = 0;
  /// The registration's noise scale (MotionEstimate::noise_scale): 1 where its inliers fit as
  /// their predicted noise says, larger where they fit worse. Discounts its pose-graph edge.
  double noise_scale = 1.0;
  /// Fused mode: each kind's own MSSE inliers among its matches, and the photometric weight
  /// W_P of the combined estimate (W_G = 1 / W_P; ALGORITHMS.md §5).
  int photometric_matches = 0;
  int photometric_inliers = 0;
  int geometric_matches = 0;
  int geometric_inliers = 0;
  double photometric_weight = 0.0;
  /// ICP refined the feature estimate (icp_mode on and the refinement accepted).
  bool icp_refined = false;
  /// The frame became the tracking key-frame the following frames register against.
  bool new_reference = false;
  /// The frame was added to the map as a key-frame.
  bool keyframe = false;
  /// The frame's key-frame (the latest stored at or before it): its pose-graph node and the node's
  /// generation, and the frame's pose relative to it. SlamLoop::optimized_pose() re-expresses the
  /// frame after the graph was optimised.
  int keyframe_node = -1;
  std::uint32_t keyframe_generation = 0;
  Eigen::Isometry3d T_keyframe_cam = Eigen::Isometry3d::Identity();
  /// A loop closure was accepted at this frame: a key-frame, or a frame after one while its
  /// candidates are registered (SlamConfig::loop_candidates_per_frame).
  bool loop_closure = false;
  /// Loop-closure candidates registered at this frame.
  int loop_candidates = 0;
  /// An optimised pose graph was applied at this frame: the pose jumped by the map correction,
  /// which every tracked pose took: T_world_cam(after) = map_correction * T_world_cam(before).
  /// Identity when none was applied.
  bool graph_applied = false;
  Eigen::Isometry3d map_correction = Eigen::Isometry3d::Identity();
  WheelCheck wheels;
  StageTimes times;
};

/// An accepted loop closure: the stored key-frame and the new one it was registered with, and
/// the relative pose the registration measured (the pose-graph edge).
struct LoopClosure {
  double stored_stamp_s = 0.0;
  double current_stamp_s = 0.0;
  Eigen::Isometry3d T_stored_current = Eigen::Isometry3d::Identity();
  int photometric_inliers = 0;
  int geometric_inliers = 0;
  /// The adaptive threshold ε the inliers passed.
  double threshold = 0.0;
};

/// The per-frame SLAM loop: one call per RGB-D frame returns its pose and status. Everything it
/// needs is allocated at construction.
///
/// Tracking is frame to key-frame: each frame is registered against a reference frame, and
/// becomes the reference itself once its inliers fall below `reference_min_overlap` of the
/// reference's features. While a reference holds, errors do not add up frame by frame. When the
/// reference gives no acceptable registration, or one whose inliers fit far worse than their noise
/// (`reference_max_noise_scale`), the previous frame is tried. When both fail the
/// pose is propagated at constant velocity and the reference kept, so the next frame that sees it
/// snaps back; after a failure the previous frame (at its propagated pose) bridges a lost view.
///
/// Wheel prior: process(frame, &prior) predicts the frame with the wheel motion instead of the
/// constant-velocity model, and when registration fails takes the prior as the pose (kWheels)
/// instead of extrapolating. An accepted registration is compared with the prior (Mahalanobis
/// distance with the wheel covariance plus a fixed per-frame vision noise, for the frame alone
/// and over a short window): when they agree the frame's motion is their covariance-weighted
/// combination; a registration that disagrees gives way to the wheels (kWheels). Vision keeps
/// the pose, and a wheel-slip event is counted, when the residual has had the shape one slipping
/// wheel leaves for wheel_slip_min_frames in a row (or its heading has turned one way for
/// wheel_slip_heading_frames), or a strong registration has disagreed as the base can move for
/// wheel_override_min_frames in a row (the robot moved without its wheels). A residual the base
/// cannot make (across its drive direction, in height, in tilt) is always vision's error.
///
/// Dark scenes: below `ir_switch_brightness` the features come from the pre-processed IR image.
/// At the frame where the image kind changes, features of the old kind are extracted as well and
/// registered against the reference, so the pose carries across the switch.
class SlamLoop {
 public:
  SlamLoop(const SlamConfig& config, const hal::Calibration& calibration);

  [[nodiscard]] FrameResult process(const hal::RgbdFrame& frame);
  /// As process(frame), with the wheel motion since the previous frame; null: no prior.
  [[nodiscard]] FrameResult process(const hal::RgbdFrame& frame, const MotionPrior* prior);

  /// Wheel-slip events so far: disagreements with the wheels that vision won (see the class
  /// comment).
  [[nodiscard]] int wheel_slip_events() const { return wheel_slip_events_; }

  [[nodiscard]] const PointMap& map() const { return map_; }
  [[nodiscard]] int keyframes() const { return keyframes_; }
  [[nodiscard]] int loop_closures() const { return loop_closures_; }
  /// The index-th accepted loop closure (0: the first), or null once it has left the log (the
  /// last kClosureLogMinCapacity or 4·loop_max_candidates are kept, whichever is more: read
  /// them after each frame to see every one).
  [[nodiscard]] const LoopClosure* loop_closure(int index) const;
  static constexpr int kClosureLogMinCapacity = 64;
  /// Key-frames retired from the full store.
  [[nodiscard]] int retired_keyframes() const { return retired_keyframes_; }
  /// The adaptive loop-closure threshold ε now.
  [[nodiscard]] double loop_threshold() const { return loop_threshold_.value(); }

  /// Offline replay: optimise the pose graph on the calling thread's schedule (wait for each
  /// solve), so that results do not depend on thread timing. Live runs leave it off.
  void set_synchronous_backend(bool synchronous) { synchronous_backend_ = synchronous; }
  /// End of a run: optimises the graph once more if a closure is pending (waits for it) and
  /// rebuilds the map from the stored key-frames at their optimised poses.
  void finish();
  /// The pose of a frame re-expressed on its key-frame's optimised pose: T_world_keyframe ·
  /// T_keyframe_cam, from the frame's FrameResult::keyframe_node, keyframe_generation and
  /// T_keyframe_cam. False (pose unchanged) when the key-frame was retired.
  [[nodiscard]] bool optimized_pose(int keyframe_node, std::uint32_t keyframe_generation,
                                    const Eigen::Isometry3d& T_keyframe_cam, Eigen::Isometry3d& T_world_cam) const;
  [[nodiscard]] const SlamConfig& config() const { return config_; }

 private:
  /// Camera velocity in its own frame: angular (rad/s), then linear (m/s).
  using Velocity = Eigen::Matrix<double, 6, 1>;

  /// Features of one frame with its pose.
  struct TrackedFrame {
    PhotometricFeatures features;
    geometry::GeometricFeatures geometric;  ///< Fused mode only.
    VoxelCloud cloud;  ///< Only with ICP on.
    Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
    /// Velocity at the frame, for its rolling-shutter correction.
    Velocity velocity = Velocity::Zero();
    std::int64_t id = 0;  ///< Frame number: tells the ICP whether its target changed.
  };

  /// Chooses the image to detect features on: IR when the colour image is dark (with
  /// hysteresis) or absent.
  [[nodiscard]] ImageSource choose_source(const hal::RgbdFrame& frame);
  /// The feature image of `source`, or null when the frame lacks it.
  [[nodiscard]] const cv::Mat* feature_image(const hal::RgbdFrame& frame, ImageSource source);
  /// Registers `current` against `target`: T_target_current. In fused mode the geometric
  /// features of both frames join the estimate (fused_estimate). `at_rest` is T_target_current
  /// had the camera not moved since the previous frame. Adds to the matching and estimation
  /// times.
  [[nodiscard]] MotionEstimate register_frames(const PhotometricFeatures& target, const Velocity& target_velocity,
                                               const PhotometricFeatures& current, const Velocity& current_velocity,
                                               FrameResult& result, const Eigen::Isometry3d& predicted,
                                               const Eigen::Isometry3d& at_rest,
                                               const geometry::GeometricFeatures* target_geometric = nullptr,
                                               const geometry::GeometricFeatures* current_geometric = nullptr,
                                               bool refine = true);
  /// ALGORITHMS.md §5 over the photometric correspondences already in source_points_ /
  /// target_points_ and the `geometric_count` geometric matches of the two frames already in
  /// geometric_matches_.
  [[nodiscard]] MotionEstimate fused_estimate(const geometry::GeometricFeatures& target_geometric,
                                              const Velocity& target_velocity,
                                              const geometry::GeometricFeatures& current_geometric,
                                              const Velocity& current_velocity, int geometric_count,
                                              FrameResult& result, const Eigen::Isometry3d& predicted,
                                              const Eigen::Isometry3d& at_rest, bool refine);
  /// How well the photometric estimate's inliers (the first photometric_count correspondences)
  /// fix the rotation: the largest 1σ [deg] their information leaves; infinity without an
  /// estimate.
  [[nodiscard]] double photometric_rotation_sigma_deg(const MotionEstimate& photometric,
                                                      std::size_t photometric_count) const;
  /// The last fused registration's photometric estimate fixes the motion too poorly to go without
  /// the geometric ICP: too few inliers, or inliers that fix the rotation worse than the bound.
  [[nodiscard]] bool photometric_needs_refinement(double above_rotation_sigma_deg) const;
  /// Whether fused mode's ICP prior is the base's drivable step combined with the feature
  /// estimate (a differential-drive base with fused_icp_base_kinematics), not the estimate alone.
  [[nodiscard]] bool icp_prior_is_drivable_step() const {
    return config_.fused_icp_base_kinematics != 0 && differential_drive_;
  }
  /// The ICP prior of fused mode where the view leaves the motion free (see
  /// SlamConfig::fused_icp_base_kinematics): `registered` tells whether `feature` is a registration.
  [[nodiscard]] geometry::IcpPrior fused_icp_prior(const Eigen::Isometry3d& at_rest, const Eigen::Isometry3d& predicted,
                                                   const MotionEstimate& feature, bool registered,
                                                   const graph::Matrix6d& feature_information) const;
  /// `point`, seen in image row `row`, moved to the frame's mid-exposure camera pose.
  [[nodiscard]] Eigen::Vector3f rolling_shutter_corrected(const Eigen::Vector3f& point, double row,
                                                          const Velocity& velocity) const;
  /// Checks an estimate of T_target_current; on success writes T_world_current, otherwise
  /// `reason` (when still empty).
  /// `predicted_step` is the motion expected from the previous frame (prior or constant velocity).
  /// `resuming`: after failed frames, against the reference, whose pose was measured; the
  /// prediction is then an extrapolation and not checked against, but the estimate needs the
  /// inliers that keep a reference.
  [[nodiscard]] bool accept(const MotionEstimate& estimate, const Eigen::Isometry3d& T_world_target,
                            const Eigen::Isometry3d& T_world_previous, const Eigen::Isometry3d& predicted_step,
                            Eigen::Isometry3d& T_world_current, std::string_view& reason,
                            bool resuming = false) const;
  void refine_with_icp(const TrackedFrame& target, const TrackedFrame& current, FrameResult& result);
  void add_keyframe_to_map(const hal::RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam, StoredKeyframe* stored);
  /// Stores the frame as a key-frame: graph node, sequential edge from the previous key-frame,
  /// then the loop-closure search.
  void store_keyframe(const hal::RgbdFrame& frame, bool have_depth, FrameResult& result);
  /// Pose-graph information of a registration from its inlier count and noise scale.
  [[nodiscard]] graph::Matrix6d registration_information(int inliers, double noise_scale) const;
  /// Information added to every sequential registration so that a direction the surfaces leave
  /// free keeps the graph non-singular.
  [[nodiscard]] graph::Matrix6d sequential_information_floor() const;
  /// On a differential-drive base: an edge holding the base's height, roll and pitch between
  /// two key-frames (graph_planar_sigma_*).
  void add_planar_edge(int from_node, int to_node, const Eigen::Isometry3d& T_from_to);
  /// Sets current_covariance_: the frame registered against `target`, whose pose covariance
  /// relative to the latest key-frame is `target_covariance` (null: not registered, and
  /// `target_covariance` is the previous frame's).
  void chain_covariance(const TrackedFrame* target, const Eigen::Matrix<double, 6, 6>& target_covariance,
                        const FrameResult& result);
  /// Starts the loop-closure search of the new key-frame in `slot`: picks the nearest stored
  /// key-frames as candidates and keeps the key-frame's whole geometric features for them where
  /// the search carries over into later frames.
  void start_loop_search(int slot);
  /// Registers up to `count` pending candidates of the search against its key-frame (all when
  /// `count` is 0); adds accepted closures to the graph.
  void continue_loop_search(int count, FrameResult& result);
  /// Registers one candidate; adds it to the graph if it closes a loop.
  void try_loop_candidate(StoredKeyframe& stored, FrameResult& result);
  /// Submits a pending graph and applies a finished optimisation (moving the tracking state by
  /// the correction).
  void run_backend(FrameResult& result);
  void apply_optimized_graph(FrameResult& result);
  /// Wheel edges: the wheel motion since the last key-frame, composed frame by frame with its
  /// covariance; invalid after a frame without a prior.
  void accumulate_wheel_motion(const MotionPrior* prior);
  void add_wheel_edge(int from_node, int to_node);
  /// Moves every pose the tracking holds by a world-frame correction.
  void correct_tracking(const Eigen::Isometry3d& correction);
  /// Geometric mode: depth-only registration of each frame against the previous one.
  [[nodiscard]] FrameResult process_geometric(const hal::RgbdFrame& frame, const MotionPrior* prior);
  /// Motion predicted from the previous frame to this one: the prior's, else constant velocity.
  [[nodiscard]] const Eigen::Isometry3d& predicted_motion(const MotionPrior* prior) const {
    return prior != nullptr ? prior->T_previous_current : last_motion_;
  }
  /// With a prior: compares an accepted registration (result.T_world_cam) with it and decides
  /// which source the frame keeps; false when the wheels overrule the registration.
  [[nodiscard]] bool check_against_wheels(const MotionPrior& prior, const Eigen::Isometry3d& T_world_previous,
                                          int inliers, FrameResult& result);
  /// The least heading a slip adds per frame: wheel_slip_yaw_deg reached in wheel_slip_min_frames.
  [[nodiscard]] double least_slip_turn_deg() const {
    return config_.wheel_slip_yaw_deg / config_.wheel_slip_min_frames;
  }
  void clear_wheel_window() {
    wheel_window_size_ = 0;
    wheel_window_next_ = 0;
  }
  /// The registered motion less the wheels', in base terms (the WheelCheck's *_residual fields).
  void describe_in_base_frame(const Eigen::Isometry3d& registered, const Eigen::Isometry3d& wheels,
                              WheelCheck& check) const;
  /// The tail every mode shares: a failed frame takes the prior, or extrapolates or holds the
  /// pose; a tracked one updates the motion model; then key-frame and map.
  void finish_frame(const hal::RgbdFrame& frame, bool have_depth, const Eigen::Isometry3d& T_world_previous,
                    const MotionPrior* prior, FrameResult& result);

  SlamConfig config_;
  DepthCameraModel camera_;
  /// The camera's mounting on the base, to compare registered and wheel motion in base terms.
  Eigen::Isometry3d T_base_cam_ = Eigen::Isometry3d::Identity();
  /// The calibration describes a differential-drive base (SlamConfig::fused_icp_base_kinematics).
  bool differential_drive_ = false;
  /// The last fused registration's photometric inliers and their rotation uncertainty.
  int last_photometric_inliers_ = 0;
  double last_photometric_rotation_sigma_deg_ = 0.0;
  OrbFrontend orb_;
  OrbFrontend infrared_orb_;
  MutualHammingMatcher matcher_;
  parallel::ThreadTeam team_;  // before the estimator and front-ends that use it
  // Fused mode with 2+ threads: extracts the ORB features while the geometric front-end runs on
  // the team. Declared after the front-ends, so stopped before they go.
  parallel::Companion companion_;
  MotionEstimator estimator_;
  PointMap map_;
  InfraredFilter infrared_filter_;
  IcpRefiner icp_;

  cv::Mat gray_;
  bool gray_valid_ = false;
  cv::Mat infrared_;
  bool infrared_valid_ = false;
  bool infrared_active_ = false;

  // Reference, previous and current frame; the reference and the previous frame may be the same
  // one. Slot indices rotate instead of copying features.
  std::array<TrackedFrame, 3> frames_;
  int reference_ = -1;
  int reference_inliers_ = 0;
  int previous_ = -1;
  std::int64_t frame_counter_ = 0;
  double previous_stamp_s_ = 0.0;
  /// Features of the other image kind, at a frame where the kind switches.
  PhotometricFeatures bridge_;

  // Geometric mode only (sized at construction when the mode is geometric).
  geometry::GeometricFrontend geometric_;
  std::array<geometry::GeometricFeatures, 2> geometric_features_;
  int geometric_previous_ = -1;
  Eigen::Isometry3d T_world_geometric_previous_ = Eigen::Isometry3d::Identity();
  /// Pose of the frame whose features are geometric_previous_ (older than the previous frame
  /// when frames without features came in between).
  Eigen::Isometry3d T_world_geometric_target_ = Eigen::Isometry3d::Identity();

  // Fused mode: the geometric matches of one registration and each correspondence's kind weight.
  geometry::GeometricCorrespondences geometric_matches_;
  /// The fused ICP refinement's prior strength (fused_icp_prior_sigma_*), as information.
  Eigen::Matrix<double, 6, 1> icp_prior_information_ = Eigen::Matrix<double, 6, 1>::Zero();
  std::vector<double> kind_weights_;

  std::vector<FeatureMatch> matches_;
  std::vector<Eigen::Vector3f> source_points_;
  std::vector<Eigen::Vector3f> target_points_;
  std::vector<double> correspondence_sigma_m_;

  /// T_previous_current of the last registered frame: the constant-velocity model.
  Eigen::Isometry3d last_motion_ = Eigen::Isometry3d::Identity();
  /// Failed frames since the last registered one.
  int failed_in_a_row_ = 0;
  /// The current frame resumed tracking against the reference after failed frames.
  bool resumed_tracking_ = false;
  /// Pose of the last registered frame.
  Eigen::Isometry3d T_world_last_tracked_ = Eigen::Isometry3d::Identity();
  /// Information of the current frame's accepted registration where it was modelled (see
  /// MotionEstimate::information): the weight of a sequential edge the frame starts.
  Eigen::Matrix<double, 6, 6> accepted_information_ = Eigen::Matrix<double, 6, 6>::Zero();
  /// Covariances, relative to the latest key-frame, of the current, previous and reference
  /// frames' poses (right perturbation in each frame): every registration adds its own on top of
  /// its target's, so a sequential edge is as uncertain as the chain of registrations it spans
  /// (see chain_covariance). The fused and photometric modes; the geometric mode weights its
  /// edges by inlier count.
  Eigen::Matrix<double, 6, 6> current_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> previous_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 6> reference_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  /// The current frame's own registration covariance, in its frame.
  Eigen::Matrix<double, 6, 6> step_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  /// The current frame became a stored key-frame (the chain restarts at it).
  bool chain_restarted_ = false;

  /// Last compared frames' residuals from the prior (ring of wheel_gate_window_frames), for the
  /// window test: slip adds up frame after frame, noise only as its square root.
  struct WheelResidual {
    Eigen::Matrix<double, 6, 1> residual = Eigen::Matrix<double, 6, 1>::Zero();
    Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  };
  std::vector<WheelResidual> wheel_window_;
  std::size_t wheel_window_next_ = 0;
  std::size_t wheel_window_size_ = 0;
  int slip_shaped_in_a_row_ = 0;
  /// Frames in a row whose heading residual reached wheel_slip_yaw_deg turning turning_sign_'s way.
  int turning_in_a_row_ = 0;
  int turning_sign_ = 0;
  int disagree_in_a_row_ = 0;
  /// Vision won the current disagreement (see check_against_wheels).
  bool vision_holds_ = false;
  /// The heading residual's sign when vision won for a slip; 0 when it won otherwise.
  int slip_sign_ = 0;
  int wheel_slip_events_ = 0;
  Eigen::Isometry3d T_world_last_keyframe_ = Eigen::Isometry3d::Identity();
  int keyframes_ = 0;
  std::mt19937 map_sampler_;

  // Back-end. The current frame's features (set before finish_frame) are what a new key-frame
  // stores.
  const PhotometricFeatures* current_photometric_ = nullptr;
  const geometry::GeometricFeatures* current_geometric_ = nullptr;
  Velocity current_velocity_ = Velocity::Zero();
  KeyframeStore keyframe_store_;
  graph::PoseGraph graph_;
  graph::BackgroundOptimizer optimizer_;
  graph::OptimizedPoses optimized_;
  AdaptiveLoopThreshold loop_threshold_;
  int latest_keyframe_slot_ = -1;
  std::int64_t keyframe_sequence_ = 0;
  double path_m_ = 0.0;
  int loop_closures_ = 0;
  int retired_keyframes_ = 0;
  bool graph_pending_ = false;
  Eigen::Isometry3d wheel_since_keyframe_ = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> wheel_since_keyframe_covariance_ = Eigen::Matrix<double, 6, 6>::Zero();
  bool wheel_since_keyframe_valid_ = false;
  bool synchronous_backend_ = false;
  /// A stored key-frame near the searching one: the nearest are registered first.
  struct LoopCandidate {
    double distance_m = 0.0;
    int slot = -1;
    std::int64_t sequence = 0;  ///< the slot's key-frame when chosen (it may be retired since)
    bool operator<(const LoopCandidate& other) const {
      return distance_m < other.distance_m || (distance_m == other.distance_m && slot < other.slot);
    }
  };
  /// The loop-closure search under way (set-up sized): its key-frame, its candidates, nearest
  /// first, up to loop_max_candidates of them, and the next one to register.
  std::vector<LoopCandidate> loop_candidates_;
  std::size_t loop_candidates_tried_ = 0;
  std::size_t loop_candidates_next_ = 0;
  int loop_search_slot_ = -1;
  std::int64_t loop_search_sequence_ = 0;
  /// The searching key-frame's features as extracted (the store keeps a thinned cloud and no
  /// block means, which the ICP refinement of a closure uses): the frame's own while the search
  /// ends in its frame, else loop_search_copy_; null without geometry.
  const geometry::GeometricFeatures* loop_search_geometric_ = nullptr;
  geometry::GeometricFeatures loop_search_copy_;
  /// The latest accepted closures, by index modulo the size (set-up sized).
  std::vector<LoopClosure> closure_log_;
};

}  // namespace rankslam::slam
