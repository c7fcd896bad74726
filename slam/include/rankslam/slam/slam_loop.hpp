#pragma once

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/geometry/frontend.hpp"
#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/nav/wheel_arbiter.hpp"
#include "rankslam/parallel/companion.hpp"
#include "rankslam/slam/backend.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/frame_images.hpp"
#include "rankslam/slam/frame_result.hpp"
#include "rankslam/slam/keyframe_store.hpp"
#include "rankslam/slam/local_mapper.hpp"
#include "rankslam/slam/loop_closer.hpp"
#include "rankslam/slam/relocaliser.hpp"
#include "rankslam/slam/map_builder.hpp"
#include "rankslam/slam/map_file.hpp"
#include "rankslam/slam/point_map.hpp"
#include "rankslam/slam/registrar.hpp"
#include "rankslam/slam/tracker.hpp"
#include "rankslam/slam/wide_closer.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>

namespace rankslam::slam {

/// The per-frame SLAM loop: one call per RGB-D frame returns its pose and status. Everything it
/// needs is allocated at construction. Per frame it calls its parts in turn: the tracker of the
/// configured mode (tracker.hpp: registration, motion model, the wheel/vision arbiter's verdict),
/// the key-frame decision and store, the loop closer, the back-end and the map.
///
/// Wheel prior: process(frame, &prior) predicts the frame with the wheel motion instead of the
/// constant-velocity model, and when registration fails takes the prior as the pose (kWheels)
/// instead of extrapolating. An accepted registration that disagrees with the prior gives way to
/// the wheels unless the arbiter (nav::WheelArbiter) finds the wheels slipping or overruled.
///
/// Dark scenes: below `ir_switch_brightness` the features come from the pre-processed IR image
/// (FrameImages), and the tracker carries the pose across the switch.
class SlamLoop {
 public:
  /// `vocabulary`: the wide-angle camera's place-recognition words (null: the built-in ones).
  SlamLoop(const SlamConfig& config, const hal::Calibration& calibration, const wide::Vocabulary* vocabulary = nullptr);

  [[nodiscard]] FrameResult process(const hal::RgbdFrame& frame);
  /// As process(frame), with the wheel motion since the previous frame; null: no prior.
  [[nodiscard]] FrameResult process(const hal::RgbdFrame& frame, const nav::MotionPrior* prior);
  /// As process(frame, prior), with the wide-angle camera's image paired with the frame (null:
  /// none); used where the calibration holds the wide-angle camera (docs/methods.md §14).
  [[nodiscard]] FrameResult process(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, const cv::Mat* wide);

  /// What the wide-angle camera added to the map; null where it takes no part (no `fisheye` in
  /// the calibration, or slam.wide_*_candidates both 0).
  [[nodiscard]] const WideCounters* wide_counters() const { return wide_ ? &wide_->counters() : nullptr; }
  /// The index-th RGBD–mono edge (see WideCloser::edge); null without the wide-angle camera.
  [[nodiscard]] const LoopClosure* wide_edge(std::uint64_t index) const { return wide_ ? wide_->edge(index) : nullptr; }

  /// Wheel-slip events so far: disagreements with the wheels that vision won (see the class
  /// comment).
  [[nodiscard]] int wheel_slip_events() const { return arbiter_.slip_events(); }

  [[nodiscard]] const PointMap& map() const { return map_.map(); }
  [[nodiscard]] int keyframes() const { return keyframes_; }
  [[nodiscard]] int loop_closures() const { return loop_closer_.closures(); }
  /// What local mapping did (docs/methods.md §18); null where it is off.
  [[nodiscard]] const LocalMapCounters* local_map() const {
    return local_.enabled() ? &local_.counters() : nullptr;
  }
  /// Closures that passed every check but the stored key-frame's neighbours' (docs/methods.md §10).
  [[nodiscard]] int loop_closures_refuted() const { return loop_closer_.refuted(); }
  /// The index-th accepted loop closure (0: the first), or null once it has left the log (the
  /// last LoopCloser::kClosureLogMinCapacity or 4·loop_max_candidates are kept, whichever is
  /// more: read them after each frame to see every one).
  [[nodiscard]] const LoopClosure* loop_closure(int index) const { return loop_closer_.closure(index); }
  /// The store holds a map of an earlier run (set-up, before the first frame): frames are kLost
  /// until one is found in it, and poses are in its frame from then on.
  void search_loaded_map();
  /// Frames found in the stored key-frames after tracking was lost (or in a loaded map).
  [[nodiscard]] int relocalisations() const { return relocalisations_; }
  /// Key-frames retired from the full store.
  [[nodiscard]] int retired_keyframes() const { return retired_keyframes_; }
  /// The adaptive loop-closure threshold ε now.
  [[nodiscard]] double loop_threshold() const { return loop_closer_.threshold(); }

  /// Offline replay: optimise the pose graph on the calling thread's schedule (wait for each
  /// solve), so that results do not depend on thread timing. Live runs leave it off.
  void set_synchronous_backend(bool synchronous) {
    backend_.set_synchronous(synchronous);
    local_.set_synchronous(synchronous);
    if (wide_) wide_->set_synchronous(synchronous);
  }
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

  /// Writes the back-end's map — stored key-frames, pose graph, loop threshold (map_file.hpp) —
  /// to `path` atomically; between frames or after finish(). Empty on success, else a message
  /// naming the file.
  [[nodiscard]] std::string save_map(const std::filesystem::path& path) const;
  /// Set-up, before the first frame: replaces the back-end's map with the one saved in `path`
  /// and rebuilds the point map from it; new key-frames continue its sequence and path. Frames
  /// are kLost until one is found in it (search_loaded_map). Throws std::runtime_error naming the file and the fault, the
  /// map then empty.
  MapFileInfo load_map(const std::filesystem::path& path);
  /// Set-up (allocates): a snapshot sized for this loop's map.
  [[nodiscard]] std::unique_ptr<MapSnapshot> make_map_snapshot() const;
  /// Copies the map as save_map would write it into `snapshot` (no allocation; features are
  /// copied only for the key-frames stored since the snapshot was last filled).
  void snapshot_map(MapSnapshot& snapshot) const;
  [[nodiscard]] const KeyframeStore& keyframe_store() const { return keyframe_store_; }
  [[nodiscard]] const graph::PoseGraph& pose_graph() const { return backend_.graph(); }

 private:
  /// The key-frame part of a frame: a frame far enough from the latest key-frame becomes one;
  /// then the loop search, the back-end and the frame's link to its key-frame.
  void finish_frame(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, const cv::Mat* wide,
                    FrameResult& result);
  /// Stores the frame as a key-frame: graph node, sequential edge from the previous key-frame,
  /// map points, then the loop-closure search.
  void store_keyframe(const hal::RgbdFrame& frame, bool have_depth, FrameResult& result);
  /// Submits a pending graph and applies a finished optimisation (moving the tracking state by
  /// the correction).
  void run_backend(FrameResult& result);
  /// Relocalisation (docs/methods.md §13): after relocalise_after_failed_frames failed frames
  /// without wheels, a sudden drop of image inliers without wheels, or until a loaded map is
  /// found, the frame is searched for in the stored key-frames. A place found where tracking went
  /// on elsewhere (a kidnapped robot) or failed moves the pose there; in a loaded map not yet
  /// found, and on a drop neither found nor explained by tracking, the status is kLost.
  void relocalise(FrameResult& result);
  /// Starts a search of the store afresh.
  void start_search();
  /// Whether the frame registers against a key-frame made before the search around tracking's
  /// pose with at least these inliers (all, and photometric) and agrees with tracking.
  [[nodiscard]] bool tracking_registers(const FrameResult& result, int min_inliers, int min_photometric_inliers);
  /// The path from the stored key-frame in `slot` to a frame at `T_world_cam` (through the latest
  /// key-frame); the drift allowances count it.
  [[nodiscard]] double path_since(int slot, const Eigen::Isometry3d& T_world_cam) const;
  /// Moves every pose the tracking holds by a world-frame correction.
  void correct_tracking(const Eigen::Isometry3d& correction);

  SlamConfig config_;
  camera::DepthCameraModel camera_;
  parallel::ThreadTeam team_;  // before the parts that use it
  // Runs the fused tracker's ORB extraction beside the geometric front-end on the team; stopped
  // before the parts it works for go.
  parallel::Companion companion_;
  FrameImages images_;
  MapBuilder map_;
  geometry::GeometricFrontend geometric_;
  /// Registration of one frame's features against another's, for tracking and loop closure.
  Registrar registrar_;
  nav::WheelArbiter arbiter_;
  KeyframeStore keyframe_store_;
  Backend backend_;
  LocalMapper local_;
  LoopCloser loop_closer_;
  Relocaliser relocaliser_;
  std::unique_ptr<Tracker> tracker_;
  /// The wide-angle camera's part; null without one. Goes before the store and back-end it uses.
  std::unique_ptr<WideCloser> wide_;
  /// Consecutive frames whose registration failed without wheels.
  int failed_in_a_row_ = 0;
  /// The previous frame's photometric matches (0 unless it was tracked).
  int last_photometric_matches_ = 0;
  /// Searching the stored key-frames (for searched_frames_ frames).
  bool searching_ = false;
  int searched_frames_ = 0;
  int tracked_while_searching_ = 0;
  /// The newest key-frame when the search started: later ones were made by tracking since.
  std::int64_t search_start_sequence_ = 0;
  /// False: the poses tracking gives are not in the map's frame (a loaded map not found yet, or
  /// `lost_by_doubt_`: since a doubted frame its image could have confirmed and did not).
  bool in_map_ = true;
  bool lost_by_doubt_ = false;
  int relocalisations_ = 0;

  Eigen::Isometry3d T_world_last_keyframe_ = Eigen::Isometry3d::Identity();
  int keyframes_ = 0;
  int latest_keyframe_slot_ = -1;
  std::int64_t keyframe_sequence_ = 0;
  double path_m_ = 0.0;
  int retired_keyframes_ = 0;
  /// The calibration and configuration a saved map is tied to.
  MapDigests map_digests_;
};

}  // namespace rankslam::slam
