#pragma once

// Local bundle adjustment of RGB-D key-frames (docs/methods.md §18): the world poses of a window
// of key-frames and the landmarks they share. Each observation is a camera-frame point measured
// from depth, whitened by its own noise (along the ray the depth error, across it the keypoint's
// pixel error at its depth), under a Huber loss; the registration edges between the key-frames
// join as priors, so a key-frame that few landmarks see keeps its registered pose. The first pose
// is held (the gauge). Buffers are sized at configure(); the solve's own allocations are Ceres'
// (the mapping thread's), bounded by the capacity.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace rankslam::graph {

struct LocalBundleCapacity {
  int max_poses = 0;
  int max_landmarks = 0;
  int max_observations = 0;
  int max_edges = 0;
};

struct LocalBundleSummary {
  /// True when the poses and landmarks were updated with a usable solution.
  bool ok = false;
  int iterations = 0;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  /// Observations whose whitened error ends within the Huber threshold.
  int inlier_observations = 0;
  /// Static text saying how the solve ended.
  std::string_view message;
};

class LocalBundle {
 public:
  using Matrix6d = Eigen::Matrix<double, 6, 6>;

  /// Set-up (allocates). Error text naming the field, or empty.
  [[nodiscard]] std::string configure(const LocalBundleCapacity& capacity);
  [[nodiscard]] const LocalBundleCapacity& capacity() const { return capacity_; }
  /// Empties the problem (no allocation).
  void clear();

  /// A pose's index, or -1 when full or not a finite rigid transform.
  int add_pose(const Eigen::Isometry3d& T_world_cam);
  /// A landmark's index, or -1 when full or not finite.
  int add_landmark(const Eigen::Vector3d& p_world);
  /// Landmark `landmark` seen from pose `pose` at `point_cam`, its error whitened by
  /// `sqrt_information` (r = S·(T_cam_world·p − point_cam)). False when full or out of range.
  bool add_observation(int pose, int landmark, const Eigen::Vector3d& point_cam, const Eigen::Matrix3d& sqrt_information);
  /// A prior on pose `to` in the frame of pose `from` (the pose graph's edge residual). False
  /// when full, out of range or the information is not positive definite.
  bool add_edge(int from, int to, const Eigen::Isometry3d& T_from_to, const Matrix6d& information);

  [[nodiscard]] int poses() const { return pose_count_; }
  [[nodiscard]] int landmarks() const { return landmark_count_; }
  [[nodiscard]] int observations() const { return observation_count_; }

  /// Levenberg–Marquardt with landmarks eliminated (Schur), pose 0 held, observations under a
  /// Huber loss of `huber` whitened units. Poses and landmarks are written back only when the
  /// solution is usable.
  LocalBundleSummary solve(int max_iterations, double huber);

  [[nodiscard]] Eigen::Isometry3d pose(int index) const;
  [[nodiscard]] Eigen::Vector3d landmark(int index) const;
  /// Whether observation index's whitened error is within the Huber threshold of the last solve.
  [[nodiscard]] bool inlier(int index) const { return inlier_[static_cast<std::size_t>(index)] != 0; }
  /// The pose and the landmark of observation index.
  [[nodiscard]] int observation_pose(int index) const { return observations_[static_cast<std::size_t>(index)].pose; }
  [[nodiscard]] int observation_landmark(int index) const {
    return observations_[static_cast<std::size_t>(index)].landmark;
  }
  [[nodiscard]] Eigen::Vector3d residual(int index) const { return whitened_error(observations_[static_cast<std::size_t>(index)]); }

 private:
  struct Observation {
    int pose = 0;
    int landmark = 0;
    Eigen::Vector3d point_cam = Eigen::Vector3d::Zero();
    Eigen::Matrix3d sqrt_information = Eigen::Matrix3d::Identity();
  };
  struct Prior {
    int from = 0;
    int to = 0;
    Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
    Matrix6d sqrt_information = Matrix6d::Identity();
  };

  [[nodiscard]] Eigen::Vector3d whitened_error(const Observation& observation) const;

  LocalBundleCapacity capacity_;
  std::vector<double> pose_parameters_;      // per pose q (x, y, z, w), t (x, y, z)
  std::vector<double> landmark_parameters_;  // per landmark x, y, z
  std::vector<Observation> observations_;
  std::vector<Prior> priors_;
  std::vector<std::uint8_t> inlier_;
  int pose_count_ = 0;
  int landmark_count_ = 0;
  int observation_count_ = 0;
  int prior_count_ = 0;
};

}  // namespace rankslam::graph
