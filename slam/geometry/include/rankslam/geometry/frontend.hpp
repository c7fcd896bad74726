#pragma once

// The geometric front-end (docs/methods.md §3–§5, thesis ch. 4–5): depth image → sampled cloud with
// normals → ROS / IS3D keypoints → SHOT descriptors → mutual matches → MSSE rigid registration.
// Depth only: it works where the colour image has no texture.
//
//   GeometricFrontend frontend;
//   if (auto error = frontend.configure(camera, config); !error.empty()) fail(error);
//   GeometricFeatures previous = frontend.make_features(), current = frontend.make_features();
//   frontend.extract(depth, current);                       // per frame, no allocation
//   const FrameRegistration r = frontend.register_frames(previous, current);
//   if (r.ok) T_world_cur = T_world_prev * r.T_previous_current;
//   std::swap(previous, current);
//
// For fused registration (§5) correspondences() hands the geometric matches to the caller's own
// MSSE as 3D–3D correspondences with per-match noise scales.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include "rankslam/geometry/cloud.hpp"
#include "rankslam/geometry/config.hpp"
#include "rankslam/geometry/icp.hpp"
#include "rankslam/geometry/keypoints.hpp"
#include "rankslam/geometry/matching.hpp"
#include "rankslam/geometry/shot.hpp"
#include "rankslam/geometry/status.hpp"
#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/rigid.hpp"
#include "rankslam/robust/workspace.hpp"
#include "rankslam/camera/depth_camera.hpp"

namespace rankslam::geometry {

/// Latency of each stage of the last extract() / register_frames() call, milliseconds, for logs
/// and benchmarks: monotonic wall-clock time, since with a thread team a stage's work is spread
/// over threads and its latency is what the frame waits for.
struct StageTimes {
  double cloud_ms = 0.0;        ///< resolution, voxel grid, block means, normals
  double keypoints_ms = 0.0;    ///< ROS / IS3D / uniform selection
  double descriptors_ms = 0.0;  ///< SHOT
  double matching_ms = 0.0;     ///< mutual nearest neighbours
  double msse_ms = 0.0;         ///< rigid MSSE over the matches
  double icp_ms = 0.0;          ///< coarse and fine ICP
};

/// Set-up sizes of a front-end's fixed buffers.
struct FrontendCapacities {
  /// Voxels of the sampled cloud (thesis: 4 000–5 000 at C = 11); more make the leaf grow.
  int max_sampled_points = 16384;
  /// Keypoints (and descriptors) per frame; at least config.max_keypoints.
  int max_keypoints = 1000;
};

/// Keypoints of one frame with their descriptors. Sized once by GeometricFrontend::make_features
/// (or reserve); `count` entries are valid. Copyable: a key-frame store can keep them.
struct GeometricFeatures {
  std::vector<Eigen::Vector3f> points_cam;  ///< keypoint positions (voxel centroids), camera frame
  std::vector<Eigen::Vector3f> normals;     ///< unit normals, facing the camera
  std::vector<float> descriptors;           ///< count × kShotSize, row-major, unit L2 norm
  std::vector<float> sigma_m;               ///< predicted position noise σ per keypoint [m]
  int count = 0;

  /// The whole sampled cloud (voxel centroids, normals, mean pixels) for the ICP refinement.
  std::vector<Eigen::Vector3f> cloud_points;
  std::vector<Eigen::Vector3f> cloud_normals;
  std::vector<Eigen::Vector2f> cloud_pixels;
  std::vector<float> cloud_curvature;
  int cloud_count = 0;
  /// Means of the 4 × 4 pixel blocks off depth edges (at least half full): the dense source of
  /// the fine ICP stage.
  std::vector<Eigen::Vector3f> block_points;
  int block_count = 0;

  // Frame statistics (for logs).
  int dense_points = 0;       ///< valid pixels after the pass-through
  int sampled_points = 0;     ///< voxel centroids with a normal
  int keypoint_candidates = 0;///< before the max_keypoints cap and descriptor failures
  float resolution_m = 0.0F;  ///< φ
  float voxel_leaf_m = 0.0F;  ///< ρ

  /// Set-up (allocates): room for `capacity` keypoints, `cloud_capacity` sampled points and
  /// `block_capacity` block means.
  void reserve(int capacity, int cloud_capacity, int block_capacity);
  [[nodiscard]] int capacity() const { return static_cast<int>(sigma_m.size()); }
  [[nodiscard]] const float* descriptor(int i) const {
    return descriptors.data() + static_cast<std::ptrdiff_t>(i) * kShotSize;
  }
  [[nodiscard]] std::span<const Eigen::Vector3f> points() const {
    return {points_cam.data(), static_cast<std::size_t>(count)};
  }
  /// Copies the filled part of `from` (keypoints, cloud, block means, statistics) into this
  /// one's room without allocating. False, and this one left empty, where it does not fit.
  bool assign_from(const GeometricFeatures& from);
};

/// Geometric matches as 3D–3D correspondences for robust::RigidModel: column i of `current`
/// (src, camera frame of the current image) matches column i of `previous` (dst), so MSSE
/// estimates T_previous_current. sigma_m[i] is the match's noise scale
/// sqrt(σ_prev² + σ_cur²), as robust::correspondence_sigmas_m composes it.
struct GeometricCorrespondences {
  Eigen::Matrix3Xd current;
  Eigen::Matrix3Xd previous;
  std::vector<double> sigma_m;
  std::vector<DescriptorMatch> matches;  ///< a: index in previous, b: index in current
  int count = 0;

  void reserve(int capacity);
};

/// Where the refined motion started from.
enum class RefinementStart : std::uint8_t {
  kNone,   ///< No ICP (disabled, or it failed from every start): the MSSE estimate as is.
  kMsse,   ///< From the MSSE estimate of the descriptor matches.
  kGuess,  ///< From the caller's motion guess (MSSE failed or fitted worse).
};

/// Result of GeometricFrontend::register_frames.
struct FrameRegistration {
  bool ok = false;
  GeometryStatus status = GeometryStatus::kNotConfigured;
  /// Maps current-frame points into the previous frame (identity unless ok).
  Eigen::Isometry3d T_previous_current = Eigen::Isometry3d::Identity();
  int matches = 0;   ///< mutual descriptor matches
  int inliers = 0;   ///< MSSE inliers k* (0 when MSSE failed)
  double scale = 0.0;  ///< MSSE noise scale of the inliers (dimensionless with per-point noise)
  bool msse_ok = false;  ///< the descriptor-match MSSE estimate succeeded
  RefinementStart refined_from = RefinementStart::kNone;
  int icp_inliers = 0;   ///< MSSE inliers of the final ICP iteration
  double icp_rms_m = 0.0;
  /// IcpResult::information of the ICP stage that set the motion (zero without ICP).
  Eigen::Matrix<double, 6, 6> icp_information = Eigen::Matrix<double, 6, 6>::Zero();
};

class GeometricFrontend {
 public:
  GeometricFrontend() = default;

  /// Set-up (allocates, may fail): copies the camera model and config, sizes every buffer.
  /// Returns an error message naming the bad field, empty on success. With a started team, the
  /// per-frame loops (normals, saliency, descriptors, matching, hypotheses) are shared among its
  /// threads; the results are the same as without. The team must outlive this front-end and be
  /// used by one front-end call at a time.
  [[nodiscard]] std::string configure(const camera::DepthCameraModel& camera,
                                      const GeometryConfig& config,
                                      const FrontendCapacities& capacities = {},
                                      parallel::ThreadTeam* team = nullptr);
  [[nodiscard]] bool configured() const { return configured_; }
  [[nodiscard]] const GeometryConfig& config() const { return config_; }

  /// A features buffer sized for this front-end (set-up).
  [[nodiscard]] GeometricFeatures make_features() const;
  [[nodiscard]] GeometricCorrespondences make_correspondences() const;

  /// Per frame, no allocation: keypoints and descriptors of a depth image (CV_16UC1, raw units,
  /// the camera's size). `out` must come from make_features(). On failure out.count is 0.
  GeometryStatus extract(const cv::Mat& depth, GeometricFeatures& out);
  /// As extract(), with a caller-chosen detector (the repeatability tool compares them).
  GeometryStatus extract(const cv::Mat& depth, KeypointMethod method, GeometricFeatures& out);

  /// Per frame, no allocation: mutual nearest-neighbour matches of the SHOT descriptors as
  /// correspondences for MSSE (see GeometricCorrespondences).
  GeometryStatus correspondences(const GeometricFeatures& previous,
                                 const GeometricFeatures& current,
                                 GeometricCorrespondences& out);

  /// Per frame, no allocation: matches, MSSE rigid registration (docs/methods.md §1, §5), then
  /// the optional ICP refinement. `T_previous_current_guess` (e.g. constant velocity or wheel
  /// odometry) is ICP's fallback start; ok means a motion was estimated from either start.
  /// `prior` (optional) holds the ICP where the clouds leave the motion free (IcpConfig::prior).
  FrameRegistration register_frames(
      const GeometricFeatures& previous, const GeometricFeatures& current,
      const Eigen::Isometry3d& T_previous_current_guess = Eigen::Isometry3d::Identity(),
      const IcpPrior& prior = IcpPrior{});

  /// The sampled cloud and keypoint indices of the last extract() (for tests and tools).
  [[nodiscard]] const SampledCloud& last_cloud() const { return cloud_; }
  [[nodiscard]] std::span<const int> last_keypoints() const {
    return {keypoints_.data(), static_cast<std::size_t>(keypoint_count_)};
  }
  [[nodiscard]] const KeypointStats& last_keypoint_stats() const { return detector_.stats(); }
  /// Stage times of the last extract() (cloud, keypoints, descriptors) and register_frames()
  /// (matching, MSSE, ICP).
  [[nodiscard]] const StageTimes& last_times() const { return times_; }
  [[nodiscard]] const camera::DepthCameraModel& camera() const { return camera_; }

 private:
  /// The processed cloud and the block means (the dense ICP source) into the features.
  void copy_cloud(GeometricFeatures& out) const;

  bool configured_ = false;
  GeometryConfig config_;
  FrontendCapacities capacities_;
  camera::DepthCameraModel camera_;
  CloudPreprocessor preprocessor_;
  SampledCloud cloud_;
  KeypointDetector detector_;
  std::vector<int> keypoints_;
  int keypoint_count_ = 0;
  PointGrid support_grid_;
  parallel::ThreadTeam* team_ = nullptr;
  std::vector<ShotEstimator> shots_;          // one per thread of the team
  std::vector<std::uint8_t> described_;       // per keypoint: its descriptor was computed
  DescriptorMatcher matcher_;
  GeometricCorrespondences scratch_;
  robust::RigidModel rigid_{3};
  robust::RobustWorkspace workspace_;
  robust::MsseTeamScratch<robust::RigidModel::Params> msse_team_;
  PlaneIcp icp_;
  StageTimes times_;
};

}  // namespace rankslam::geometry
