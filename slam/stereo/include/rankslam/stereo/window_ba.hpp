#pragma once

// Sliding-window bundle adjustment of stereo frames (Ceres): poses T_cam_world of the window's
// frames and the world points they share, reprojection error in the left and right rectified
// cameras under a Huber loss, the oldest pose held fixed (stereo fixes the scale).

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Geometry>

#include "rankslam/stereo/rectifier.hpp"

namespace rankslam::stereo {

/// One feature of a frame seen as a landmark: left pixel, and the right column when it was
/// matched in the right image too (NaN otherwise). Rectified pixels.
struct Observation {
  std::int64_t landmark = -1;
  float u = 0.0f;
  float v = 0.0f;
  float u_right = 0.0f;
};

struct WindowFrame {
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
  std::vector<Observation> observations;
};

struct Landmark {
  std::int64_t id = -1;  ///< −1: free slot
  Eigen::Vector3d p_world = Eigen::Vector3d::Zero();
  int window_observations = 0;  ///< scratch of the bundle adjustment
  std::int64_t stamp = -1;      ///< scratch of the bundle adjustment
};

/// Fixed-capacity landmark table: id i lives in slot i mod capacity, so lookups and inserts never
/// allocate; an id whose slot was taken over by a newer one is gone (tracks longer than the
/// table's turnover are cut, not corrupted).
class LandmarkStore {
 public:
  explicit LandmarkStore(int capacity) : slots_(static_cast<std::size_t>(capacity)) {}
  [[nodiscard]] Landmark* find(std::int64_t id) {
    if (id < 0 || slots_.empty()) return nullptr;
    Landmark& slot = slots_[static_cast<std::size_t>(id % static_cast<std::int64_t>(slots_.size()))];
    return slot.id == id ? &slot : nullptr;
  }
  std::int64_t create(const Eigen::Vector3d& p_world) {
    const std::int64_t id = next_id_++;
    Landmark& slot = slots_[static_cast<std::size_t>(id % static_cast<std::int64_t>(slots_.size()))];
    slot = Landmark{id, p_world, 0, -1};
    return id;
  }
  void clear() {
    for (auto& slot : slots_) slot.id = -1;
  }

 private:
  std::vector<Landmark> slots_;
  std::int64_t next_id_ = 0;
};

struct WindowBaConfig {
  /// Huber loss scale [px]: residuals beyond it count linearly (mismatches that passed MSSE).
  double huber_px = 1.0;
  /// Levenberg–Marquardt iterations per window.
  int max_iterations = 10;
};

struct WindowBaSummary {
  bool solved = false;
  int residual_blocks = 0;
  int landmarks = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
};

/// Optimises the frames' poses (frames[0] fixed) and the landmarks seen in at least two of them,
/// in place. The Ceres problem is built per call (it allocates).
WindowBaSummary adjust_window(const RectifiedRig& rig, std::span<WindowFrame* const> frames, LandmarkStore& landmarks,
                              const WindowBaConfig& config, std::int64_t stamp);

/// Motion-only refinement: T_cam_ref minimising the same robust reprojection errors of points
/// given in the reference frame (`points_ref[i]` seen at `observations[i]`). Returns false (and
/// leaves the pose) when Ceres fails.
bool refine_pose(const RectifiedRig& rig, std::span<const Eigen::Vector3d> points_ref,
                 std::span<const Observation> observations, const WindowBaConfig& config, Eigen::Isometry3d& T_cam_ref);

}  // namespace rankslam::stereo
