#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/geometry/frontend.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/parallel/companion.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/backend.hpp"
#include "rankslam/slam/frame_result.hpp"
#include "rankslam/slam/loop_closer.hpp"
#include "rankslam/slam/registrar.hpp"
#include "rankslam/slam/icp.hpp"
#include "rankslam/slam/image_source.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/orb_frontend.hpp"
#include "rankslam/slam/point_map.hpp"
#include "rankslam/nav/wheel_arbiter.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <random>
#include <string_view>
#include <vector>

namespace rankslam::slam {

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
  [[nodiscard]] FrameResult process(const hal::RgbdFrame& frame, const nav::MotionPrior* prior);

  /// Wheel-slip events so far: disagreements with the wheels that vision won (see the class
  /// comment).
  [[nodiscard]] int wheel_slip_events() const { return arbiter_.slip_events(); }

  [[nodiscard]] const PointMap& map() const { return map_; }
  [[nodiscard]] int keyframes() const { return keyframes_; }
  [[nodiscard]] int loop_closures() const { return loop_closer_.closures(); }
  /// The index-th accepted loop closure (0: the first), or null once it has left the log (the
  /// last LoopCloser::kClosureLogMinCapacity or 4·loop_max_candidates are kept, whichever is
  /// more: read them after each frame to see every one).
  [[nodiscard]] const LoopClosure* loop_closure(int index) const { return loop_closer_.closure(index); }
  /// Key-frames retired from the full store.
  [[nodiscard]] int retired_keyframes() const { return retired_keyframes_; }
  /// The adaptive loop-closure threshold ε now.
  [[nodiscard]] double loop_threshold() const { return loop_closer_.threshold(); }

  /// Offline replay: optimise the pose graph on the calling thread's schedule (wait for each
  /// solve), so that results do not depend on thread timing. Live runs leave it off.
  void set_synchronous_backend(bool synchronous) { backend_.set_synchronous(synchronous); }
  /// End of a run: optimises the graph once more if a closure is pending (waits for it) and
  /// rebuilds the map from the stored key-frames at their optimised poses.
  void finish();
  /// The pose of a frame re-expressed on its key-frame's optimised pose: T_world_keyframe ·
  /// T_keyframe_cam, from the frame's FrameResult::keyframe_node, keyframe_generation and
  /// T_keyframe_cam. False (pose unchanged) when the key-frame was retired.
  [[nodiscard]] bool optimized_pose(int keyframe_node, std::uint32_t keyframe_generation,
                                    const Eigen::Isometry3d& T_keyframe_cam, Eigen::Isometry3d& T_world_cam) const {
    return backend_.optimized_pose(keyframe_node, keyframe_generation, T_keyframe_cam, T_world_cam);
  }
  [[nodiscard]] const SlamConfig& config() const { return config_; }

 private:
  using Velocity = Registrar::Velocity;

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
  /// Sets current_covariance_: the frame registered against `target`, whose pose covariance
  /// relative to the latest key-frame is `target_covariance` (null: not registered, and
  /// `target_covariance` is the previous frame's).
  void chain_covariance(const TrackedFrame* target, const Eigen::Matrix<double, 6, 6>& target_covariance,
                        const FrameResult& result);
  /// Submits a pending graph and applies a finished optimisation (moving the tracking state by
  /// the correction).
  void run_backend(FrameResult& result);
  /// Moves every pose the tracking holds by a world-frame correction.
  void correct_tracking(const Eigen::Isometry3d& correction);
  /// Geometric mode: depth-only registration of each frame against the previous one.
  [[nodiscard]] FrameResult process_geometric(const hal::RgbdFrame& frame, const nav::MotionPrior* prior);
  /// Motion predicted from the previous frame to this one: the prior's, else constant velocity.
  [[nodiscard]] const Eigen::Isometry3d& predicted_motion(const nav::MotionPrior* prior) const {
    return prior != nullptr ? prior->T_previous_current : last_motion_;
  }
  /// The tail every mode shares: a failed frame takes the prior, or extrapolates or holds the
  /// pose; a tracked one updates the motion model; then key-frame and map.
  void finish_frame(const hal::RgbdFrame& frame, bool have_depth, const Eigen::Isometry3d& T_world_previous,
                    const nav::MotionPrior* prior, FrameResult& result);

  SlamConfig config_;
  camera::DepthCameraModel camera_;
  OrbFrontend orb_;
  OrbFrontend infrared_orb_;
  parallel::ThreadTeam team_;  // before the front-ends and the registrar that use it
  // Fused mode with 2+ threads: extracts the ORB features while the geometric front-end runs on
  // the team. Declared after the front-ends, so stopped before they go.
  parallel::Companion companion_;
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
  /// Registration of one frame's features against another's, for tracking and loop closure.
  Registrar registrar_;
  std::array<geometry::GeometricFeatures, 2> geometric_features_;
  int geometric_previous_ = -1;
  Eigen::Isometry3d T_world_geometric_previous_ = Eigen::Isometry3d::Identity();
  /// Pose of the frame whose features are geometric_previous_ (older than the previous frame
  /// when frames without features came in between).
  Eigen::Isometry3d T_world_geometric_target_ = Eigen::Isometry3d::Identity();


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

  nav::WheelArbiter arbiter_;
  Eigen::Isometry3d T_world_last_keyframe_ = Eigen::Isometry3d::Identity();
  int keyframes_ = 0;
  std::mt19937 map_sampler_;

  // Back-end. The current frame's features (set before finish_frame) are what a new key-frame
  // stores.
  const PhotometricFeatures* current_photometric_ = nullptr;
  const geometry::GeometricFeatures* current_geometric_ = nullptr;
  Velocity current_velocity_ = Velocity::Zero();
  KeyframeStore keyframe_store_;
  Backend backend_;
  LoopCloser loop_closer_;
  int latest_keyframe_slot_ = -1;
  std::int64_t keyframe_sequence_ = 0;
  double path_m_ = 0.0;
  int retired_keyframes_ = 0;
};

}  // namespace rankslam::slam
