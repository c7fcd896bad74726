#pragma once

// Keypoint detectors over the sampled cloud: ROS (thesis ch. 4, docs/methods.md §4), IS3D
// (thesis ch. 5, §4) and uniform sampling (the thesis' baseline). ROS and IS3D segment with
// MSSE from rankslam::robust.

#include <array>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rankslam/geometry/cloud.hpp"
#include "rankslam/geometry/config.hpp"
#include "rankslam/geometry/point_grid.hpp"
#include "rankslam/geometry/status.hpp"
#include "rankslam/parallel/thread_team.hpp"
#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/orientation.hpp"
#include "rankslam/robust/scalar.hpp"
#include "rankslam/robust/workspace.hpp"

namespace rankslam::geometry {

/// What the last detect() found, for logs and tests.
struct KeypointStats {
  static constexpr int kMaxOrientations = 64;
  /// ROS: group-2 size (points past the transition). IS3D: points in no dominant group.
  /// Uniform: occupied cells.
  int candidates = 0;
  /// ROS: the MSSE transition point k*. Otherwise 0.
  int transition = 0;
  /// IS3D: dominant orientations found, each a unit normal, with their group sizes.
  int orientations = 0;
  std::array<Eigen::Vector3d, kMaxOrientations> orientation{};
  std::array<int, kMaxOrientations> group_size{};
  /// Uniform: the cell edge used.
  float uniform_cell_m = 0.0F;
};

class KeypointDetector {
 public:
  /// Set-up (allocates): buffers for clouds of up to max_points points. Error message or empty.
  /// With a team, the saliency and IS3D's orientation hypotheses are shared among its threads
  /// (same keypoints).
  [[nodiscard]] std::string configure(const GeometryConfig& config, int max_points,
                                      parallel::ThreadTeam* team = nullptr);
  [[nodiscard]] bool configured() const { return max_points_ > 0; }

  /// Per frame, no allocation: writes the indices (into cloud.points) of up to
  /// config.max_keypoints keypoints to `out` and returns their number (0 on failure, with
  /// `status` saying why). `out` must hold max_keypoints entries.
  int detect(KeypointMethod method, const SampledCloud& cloud, std::span<int> out,
             GeometryStatus& status);
  int detect(const SampledCloud& cloud, std::span<int> out, GeometryStatus& status) {
    return detect(config_.keypoint_method, cloud, out, status);
  }

  /// Optional, per frame, no allocation: builds the neighbour grid that detect() of this cloud
  /// with this method would build first, so that the caller can run it beside other work (it
  /// uses no team). The next detect() of the same cloud uses it; any other detect() ignores it.
  void prepare(KeypointMethod method, const SampledCloud& cloud);

  /// Optional, per frame, no allocation: IS3D's dominant-orientation grouping of this cloud,
  /// which an IS3D detect() of it would do first, without the team, so that the caller can run
  /// it beside prepare() and other work (its hypotheses gain little from a team: the serial loop
  /// exits early on most of them). Concurrent with prepare() of the same cloud. The next detect()
  /// of the same cloud with IS3D uses it; any other detect() ignores it.
  void group_orientations(const SampledCloud& cloud);

  [[nodiscard]] const KeypointStats& stats() const { return stats_; }
  /// ROS saliency θ_i (mean squared normal angle to the N nearest sampled neighbours, rad²) of
  /// every cloud point as computed by the last ROS detection (an IS3D detection ranked by
  /// saliency computes it for its candidates only).
  [[nodiscard]] std::span<const double> saliency() const {
    return {saliency_.data(), static_cast<std::size_t>(saliency_count_)};
  }

 private:
  int detect_ros(const SampledCloud& cloud, std::span<int> out, GeometryStatus& status);
  int detect_is3d(const SampledCloud& cloud, std::span<int> out, GeometryStatus& status);
  /// IS3D's grouping: dominant orientations into grouping_, the points in none of them into
  /// remaining_ (remaining_count_ of them), assigned_ set for the grouped points. `shared`: the
  /// team's scratch for the hypotheses, or null to run them on the calling thread alone.
  void group(const SampledCloud& cloud,
             robust::MsseTeamScratch<robust::OrientationModel::Params>* shared);
  int detect_uniform(const SampledCloud& cloud, std::span<int> out, GeometryStatus& status);
  /// θ of every cloud point, or only of those with wanted[i] != 0 (the rest keep stale values).
  void compute_saliency(const SampledCloud& cloud, const std::uint8_t* wanted = nullptr);

  GeometryConfig config_;
  int max_points_ = 0;
  KeypointStats stats_;
  PointGrid grid_;
  const SampledCloud* prepared_for_ = nullptr;  // the cloud grid_ was prepared for, if any
  bool grid_prepared_ = false;                   // this detection's saliency grid is built
  const SampledCloud* grouped_for_ = nullptr;   // the cloud group_orientations() grouped, if any
  bool grouped_ = false;                         // this detection's IS3D grouping is done
  KeypointStats grouping_;                       // orientations and group sizes of the grouping
  int remaining_count_ = 0;                      // points in no dominant group
  robust::RobustWorkspace workspace_;
  robust::OrientationModel orientation_model_{1};
  parallel::ThreadTeam* team_ = nullptr;
  robust::MsseTeamScratch<robust::OrientationModel::Params> orientation_team_;
  Eigen::Matrix3Xd normals_;
  std::vector<double> saliency_;
  int saliency_count_ = 0;
  std::vector<int> remaining_;
  std::vector<int> next_remaining_;
  std::vector<std::uint8_t> assigned_;
  // Per thread of the team, max_points_ each: a cell's neighbour candidates (point index, rank
  // in the 27 cells' scan order, coordinates) and their squared distances to one point.
  std::vector<int> candidates_;
  std::vector<int> candidate_ranks_;
  std::vector<float> candidate_x_, candidate_y_, candidate_z_, candidate_d2_;
  std::vector<std::pair<float, int>> ranked_;
};

}  // namespace rankslam::geometry
