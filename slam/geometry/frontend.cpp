#include "rankslam/geometry/frontend.hpp"
#include "rankslam/core/units.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <time.h>

#include "rankslam/robust/msse.hpp"

namespace rankslam::geometry {

namespace {

// Monotonic wall-clock time in milliseconds: with a thread team a stage's work is spread over
// threads, and its latency is what the frame waits for.
double now_ms() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<double>(now.tv_sec) * 1e3 + static_cast<double>(now.tv_nsec) * 1e-6;
}

}  // namespace

void GeometricFeatures::reserve(int capacity, int cloud_capacity, int block_capacity) {
  const auto n = static_cast<std::size_t>(std::max(0, capacity));
  points_cam.assign(n, Eigen::Vector3f::Zero());
  normals.assign(n, Eigen::Vector3f::Zero());
  descriptors.assign(n * static_cast<std::size_t>(kShotSize), 0.0F);
  sigma_m.assign(n, 0.0F);
  count = 0;
  const auto m = static_cast<std::size_t>(std::max(0, cloud_capacity));
  cloud_points.assign(m, Eigen::Vector3f::Zero());
  cloud_normals.assign(m, Eigen::Vector3f::Zero());
  cloud_pixels.assign(m, Eigen::Vector2f::Zero());
  cloud_curvature.assign(m, 0.0F);
  cloud_count = 0;
  block_points.assign(static_cast<std::size_t>(std::max(0, block_capacity)), Eigen::Vector3f::Zero());
  block_count = 0;
}

bool GeometricFeatures::assign_from(const GeometricFeatures& from) {
  count = cloud_count = block_count = 0;
  if (from.count > capacity() || from.cloud_count > static_cast<int>(cloud_points.size()) ||
      from.block_count > static_cast<int>(block_points.size())) {
    return false;
  }
  const auto n = static_cast<std::size_t>(from.count);
  std::copy_n(from.points_cam.begin(), n, points_cam.begin());
  std::copy_n(from.normals.begin(), n, normals.begin());
  std::copy_n(from.descriptors.begin(), n * static_cast<std::size_t>(kShotSize), descriptors.begin());
  std::copy_n(from.sigma_m.begin(), n, sigma_m.begin());
  const auto m = static_cast<std::size_t>(from.cloud_count);
  std::copy_n(from.cloud_points.begin(), m, cloud_points.begin());
  std::copy_n(from.cloud_normals.begin(), m, cloud_normals.begin());
  std::copy_n(from.cloud_pixels.begin(), m, cloud_pixels.begin());
  std::copy_n(from.cloud_curvature.begin(), m, cloud_curvature.begin());
  std::copy_n(from.block_points.begin(), static_cast<std::size_t>(from.block_count), block_points.begin());
  count = from.count;
  cloud_count = from.cloud_count;
  block_count = from.block_count;
  dense_points = from.dense_points;
  sampled_points = from.sampled_points;
  keypoint_candidates = from.keypoint_candidates;
  resolution_m = from.resolution_m;
  voxel_leaf_m = from.voxel_leaf_m;
  return true;
}

void GeometricCorrespondences::reserve(int capacity) {
  const int n = std::max(0, capacity);
  current.setZero(3, n);
  previous.setZero(3, n);
  sigma_m.assign(static_cast<std::size_t>(n), 0.0);
  matches.assign(static_cast<std::size_t>(n), DescriptorMatch{});
  count = 0;
}

std::string GeometricFrontend::configure(const camera::DepthCameraModel& camera,
                                         const GeometryConfig& config,
                                         const FrontendCapacities& capacities,
                                         parallel::ThreadTeam* team) {
  configured_ = false;
  team_ = team;
  if (const std::string_view bad = config.validate(); !bad.empty()) {
    return "geometry config: " + std::string(bad) + " is out of range";
  }
  if (capacities.max_keypoints < config.max_keypoints) {
    return "geometry: capacities.max_keypoints (" + std::to_string(capacities.max_keypoints) +
           ") is below config max_keypoints (" + std::to_string(config.max_keypoints) + ")";
  }
  if (capacities.max_sampled_points < 3) {
    return "geometry: capacities.max_sampled_points must be at least 3";
  }
  if (config.icp_depth_limit_m(camera.depth_noise_per_m()) <= config.min_depth_m) {
    return "geometry config: icp_pass_through_margin_sigmas leaves the ICP no depth for this camera's noise";
  }
  config_ = config;
  capacities_ = capacities;
  camera_ = camera;
  if (std::string error = preprocessor_.configure(camera_, config_, capacities.max_sampled_points, team);
      !error.empty()) {
    return error;
  }
  cloud_ = preprocessor_.make_cloud();
  if (std::string error = detector_.configure(config_, capacities.max_sampled_points, team);
      !error.empty()) {
    return error;
  }
  keypoints_.assign(static_cast<std::size_t>(capacities.max_keypoints), 0);
  keypoint_count_ = 0;
  support_grid_.reserve(capacities.max_sampled_points);
  shots_.resize(static_cast<std::size_t>(parallel::team_size(team)));
  for (ShotEstimator& shot : shots_) shot.reserve(capacities.max_sampled_points);
  described_.assign(static_cast<std::size_t>(capacities.max_keypoints), 0);
  if (std::string error = matcher_.configure(capacities.max_keypoints, kShotSize,
                                             DescriptorMatcher::Kernel::kBest, team);
      !error.empty()) {
    return error;
  }
  scratch_.reserve(capacities.max_keypoints);
  rigid_ = robust::RigidModel(capacities.max_keypoints);
  workspace_.reserve(capacities.max_keypoints);
  msse_team_.reserve(team, config_.msse_hypotheses, robust::RigidModel::kSampleSize,
                     capacities.max_keypoints);
  if (std::string error = icp_.configure(
          camera_.calibration(),
          std::max(capacities.max_sampled_points, static_cast<int>(preprocessor_.blocks().front.weight.size())),
          team);
      !error.empty()) {
    return error;
  }
  configured_ = true;
  return {};
}

GeometricFeatures GeometricFrontend::make_features() const {
  GeometricFeatures features;
  features.reserve(capacities_.max_keypoints, capacities_.max_sampled_points,
                   static_cast<int>(preprocessor_.blocks().front.weight.size()));
  return features;
}

GeometricCorrespondences GeometricFrontend::make_correspondences() const {
  GeometricCorrespondences correspondences;
  correspondences.reserve(capacities_.max_keypoints);
  return correspondences;
}

void GeometricFrontend::copy_cloud(GeometricFeatures& out) const {
  std::copy_n(cloud_.points.begin(), cloud_.size, out.cloud_points.begin());
  std::copy_n(cloud_.normals.begin(), cloud_.size, out.cloud_normals.begin());
  std::copy_n(cloud_.pixels.begin(), cloud_.size, out.cloud_pixels.begin());
  std::copy_n(cloud_.curvature.begin(), cloud_.size, out.cloud_curvature.begin());
  out.cloud_count = cloud_.size;
  // A block at least half full and off depth edges: 8+ pixels averaged on one surface.
  constexpr float kMinBlockPoints = 0.5F * BlockImage::kBlock * BlockImage::kBlock;
  const BlockImage& blocks = preprocessor_.blocks();
  int n = 0;
  for (int v = 0; v < blocks.height; ++v) {
    for (int u = 0; u < blocks.width; ++u) {
      const std::size_t b = blocks.index(u, v);
      if (blocks.front.weight[b] < kMinBlockPoints || blocks.across_depth_edge(b)) continue;
      out.block_points[static_cast<std::size_t>(n++)] = blocks.front.mean(b);
    }
  }
  out.block_count = n;
}

GeometryStatus GeometricFrontend::extract(const cv::Mat& depth, GeometricFeatures& out) {
  return extract(depth, config_.keypoint_method, out);
}

GeometryStatus GeometricFrontend::extract(const cv::Mat& depth, KeypointMethod method,
                                          GeometricFeatures& out) {
  out.count = 0;
  out.cloud_count = 0;
  out.block_count = 0;
  out.dense_points = 0;
  out.sampled_points = 0;
  out.keypoint_candidates = 0;
  keypoint_count_ = 0;
  if (!configured_) return GeometryStatus::kNotConfigured;
  if (out.capacity() < config_.max_keypoints ||
      out.descriptors.size() < static_cast<std::size_t>(out.capacity()) * kShotSize ||
      out.points_cam.size() < static_cast<std::size_t>(out.capacity()) ||
      out.normals.size() < static_cast<std::size_t>(out.capacity()) ||
      out.cloud_points.size() < static_cast<std::size_t>(capacities_.max_sampled_points) ||
      out.cloud_normals.size() < out.cloud_points.size() ||
      out.cloud_pixels.size() < out.cloud_points.size() ||
      out.cloud_curvature.size() < out.cloud_points.size() ||
      out.block_points.size() < preprocessor_.blocks().front.weight.size()) {
    return GeometryStatus::kCapacityExceeded;
  }
  times_.cloud_ms = times_.keypoints_ms = times_.descriptors_ms = 0.0;
  double t0 = now_ms();
  GeometryStatus status = preprocessor_.process(depth, cloud_);
  out.dense_points = cloud_.dense_points;
  out.sampled_points = cloud_.size;
  out.resolution_m = cloud_.resolution_m;
  out.voxel_leaf_m = cloud_.voxel_leaf_m;
  if (status != GeometryStatus::kOk) return status;
  double t1 = now_ms();
  times_.cloud_ms = t1 - t0;
  // The two neighbour grids of the cloud, the keypoints' and SHOT's (cells of the support radius
  // make each query 2–3 cells a side), are serial passes; so is, in effect, IS3D's grouping of
  // the normals by dominant orientation. The grouping goes beside the two grids and the copy of
  // the cloud and block means into the features.
  const auto radius = static_cast<float>(config_.shot_radius_m);
  const auto points = cloud_.point_span();
  const auto normals = cloud_.normal_span();
  bool support_grid_built = false;
  const bool group_beside = method == KeypointMethod::kIs3d;
  parallel::for_each(team_, 2, [&](int task, int /*thread*/) {
    if (task == 0) {
      if (group_beside) {
        detector_.group_orientations(cloud_);
      } else {
        detector_.prepare(method, cloud_);
      }
    } else {
      support_grid_built = support_grid_.build(points, radius);
      if (group_beside) detector_.prepare(method, cloud_);
      copy_cloud(out);
    }
  });
  keypoint_count_ = detector_.detect(method, cloud_, keypoints_, status);
  out.keypoint_candidates = detector_.stats().candidates;
  t0 = now_ms();
  times_.keypoints_ms = t0 - t1;
  if (status != GeometryStatus::kOk) return status;

  // SHOT over the sampled cloud.
  if (!support_grid_built) return GeometryStatus::kCapacityExceeded;
  const auto a = static_cast<float>(camera_.depth_noise_per_m());
  const auto lateral = static_cast<float>(config_.lateral_sigma_m);
  // Each keypoint's descriptor goes to its own slot, on whichever thread; the described ones are
  // then packed in keypoint order, as one thread would have written them.
  constexpr int kKeypointsPerChunk = 8;
  const auto describe = [&](int begin, int end, int thread) {
    ShotEstimator& shot = shots_[static_cast<std::size_t>(thread)];
    for (int k = begin; k < end; ++k) {
      const int index = keypoints_[static_cast<std::size_t>(k)];
      float* descriptor = out.descriptors.data() + static_cast<std::ptrdiff_t>(k) * kShotSize;
      described_[static_cast<std::size_t>(k)] =
          shot.compute(points[static_cast<std::size_t>(index)], points, normals, support_grid_,
                       radius, config_.shot_min_neighbours, descriptor) == ShotResult::kOk
              ? 1
              : 0;
    }
  };
  parallel::for_chunks(team_, keypoint_count_, kKeypointsPerChunk, describe);
  int count = 0;
  for (int k = 0; k < keypoint_count_; ++k) {
    if (described_[static_cast<std::size_t>(k)] == 0) continue;
    const int index = keypoints_[static_cast<std::size_t>(k)];
    const Eigen::Vector3f& p = points[static_cast<std::size_t>(index)];
    if (count != k) {
      std::copy_n(out.descriptors.data() + static_cast<std::ptrdiff_t>(k) * kShotSize, kShotSize,
                  out.descriptors.data() + static_cast<std::ptrdiff_t>(count) * kShotSize);
    }
    const auto c = static_cast<std::size_t>(count);
    out.points_cam[c] = p;
    out.normals[c] = normals[static_cast<std::size_t>(index)];
    // σ² = σ_z² + 2σ_lat² with σ_z = a·z² (Khoshelham & Elberink 2012): one point's share of
    // robust::correspondence_sigmas_m.
    const float sigma_z = a * p.z() * p.z();
    out.sigma_m[c] = std::sqrt(sigma_z * sigma_z + 2.0F * lateral * lateral);
    ++count;
  }
  out.count = count;
  times_.descriptors_ms = now_ms() - t0;
  return count >= 3 ? GeometryStatus::kOk : GeometryStatus::kTooFewKeypoints;
}

GeometryStatus GeometricFrontend::correspondences(const GeometricFeatures& previous,
                                                  const GeometricFeatures& current,
                                                  GeometricCorrespondences& out) {
  out.count = 0;
  if (!configured_) return GeometryStatus::kNotConfigured;
  if (previous.count > capacities_.max_keypoints || current.count > capacities_.max_keypoints ||
      static_cast<int>(out.matches.size()) < std::min(previous.count, current.count) ||
      out.current.cols() < static_cast<Eigen::Index>(out.matches.size()) ||
      out.previous.cols() < static_cast<Eigen::Index>(out.matches.size()) ||
      out.sigma_m.size() < out.matches.size()) {
    return GeometryStatus::kCapacityExceeded;
  }
  if (previous.count < 3 || current.count < 3) return GeometryStatus::kTooFewKeypoints;
  const int matches = matcher_.match(previous.descriptors.data(), previous.count,
                                     current.descriptors.data(), current.count, out.matches);
  if (matches < 0) return GeometryStatus::kCapacityExceeded;
  for (int i = 0; i < matches; ++i) {
    const DescriptorMatch& m = out.matches[static_cast<std::size_t>(i)];
    out.previous.col(i) = previous.points_cam[static_cast<std::size_t>(m.a)].cast<double>();
    out.current.col(i) = current.points_cam[static_cast<std::size_t>(m.b)].cast<double>();
    const double sp = previous.sigma_m[static_cast<std::size_t>(m.a)];
    const double sc = current.sigma_m[static_cast<std::size_t>(m.b)];
    out.sigma_m[static_cast<std::size_t>(i)] = std::sqrt(sp * sp + sc * sc);
  }
  out.count = matches;
  return matches >= 3 ? GeometryStatus::kOk : GeometryStatus::kTooFewMatches;
}

FrameRegistration GeometricFrontend::register_frames(const GeometricFeatures& previous,
                                                     const GeometricFeatures& current,
                                                     const Eigen::Isometry3d& T_previous_current_guess,
                                                     const IcpPrior& prior) {
  FrameRegistration registration;
  times_.matching_ms = times_.msse_ms = times_.icp_ms = 0.0;
  double t0 = now_ms();
  registration.status = correspondences(previous, current, scratch_);
  double t1 = now_ms();
  times_.matching_ms = t1 - t0;
  registration.matches = scratch_.count;
  if (registration.status == GeometryStatus::kNotConfigured ||
      registration.status == GeometryStatus::kCapacityExceeded) {
    return registration;
  }
  if (registration.status == GeometryStatus::kOk) {
    const int n = scratch_.count;
    if (rigid_.set_correspondences(scratch_.current.leftCols(n), scratch_.previous.leftCols(n)) !=
        robust::RobustStatus::kOk) {
      registration.status = GeometryStatus::kRegistrationFailed;
    } else {
      robust::MsseConfig msse;
      msse.hypotheses = config_.msse_hypotheses;
      msse.min_inlier_fraction = config_.msse_min_inlier_fraction;
      msse.seed = static_cast<std::uint64_t>(config_.seed) * 0x9e3779b97f4a7c15ULL + 0x51ed270bULL;
      const std::span<const double> sigmas =
          config_.per_point_noise != 0
              ? std::span<const double>(scratch_.sigma_m.data(), static_cast<std::size_t>(n))
              : std::span<const double>{};
      robust::RigidMotionGate gate;
      gate.T_t_s_predicted = T_previous_current_guess;
      gate.max_translation_m = config_.motion_gate_translation_m > 0.0
                                   ? config_.motion_gate_translation_m
                                   : std::numeric_limits<double>::infinity();
      gate.max_rotation_rad = config_.motion_gate_rotation_deg > 0.0
                                  ? deg_to_rad(config_.motion_gate_rotation_deg)
                                  : std::numeric_limits<double>::infinity();
      const auto result = robust::estimate_msse(rigid_, msse, workspace_, sigmas, gate, &msse_team_);
      if (!result.ok()) {
        registration.status = result.status == robust::RobustStatus::kTooFewPoints
                                  ? GeometryStatus::kTooFewMatches
                                  : GeometryStatus::kRegistrationFailed;
      } else {
        registration.inliers = result.inlier_count;
        registration.scale = result.scale;
        if (result.inlier_count < config_.min_inliers) {
          registration.status = GeometryStatus::kRegistrationFailed;
        } else {
          registration.T_previous_current = result.model;
          registration.msse_ok = true;
          registration.status = GeometryStatus::kOk;
        }
      }
    }
  }
  registration.ok = registration.msse_ok;
  t0 = now_ms();
  times_.msse_ms = t0 - t1;
  if (config_.icp_iterations == 0 || previous.cloud_count < 3 || current.cloud_count < 3) {
    return registration;
  }

  // ICP refinement from MSSE's estimate, and from the guess when that is missing or poor.
  const IcpCloud previous_cloud{
      {previous.cloud_points.data(), static_cast<std::size_t>(previous.cloud_count)},
      {previous.cloud_normals.data(), static_cast<std::size_t>(previous.cloud_count)},
      {previous.cloud_pixels.data(), static_cast<std::size_t>(previous.cloud_count)},
      {previous.cloud_curvature.data(), static_cast<std::size_t>(previous.cloud_count)}};
  const IcpCloud current_cloud{
      {current.cloud_points.data(), static_cast<std::size_t>(current.cloud_count)},
      {current.cloud_normals.data(), static_cast<std::size_t>(current.cloud_count)},
      {current.cloud_pixels.data(), static_cast<std::size_t>(current.cloud_count)},
      {current.cloud_curvature.data(), static_cast<std::size_t>(current.cloud_count)}};
  IcpConfig coarse;
  coarse.max_iterations = config_.icp_iterations;
  coarse.max_points = config_.icp_max_points;
  coarse.max_distance_m = static_cast<float>(config_.icp_max_distance_factor) *
                          std::max(previous.voxel_leaf_m, current.voxel_leaf_m);
  coarse.min_inlier_fraction = config_.icp_min_inlier_fraction;
  coarse.max_curvature = static_cast<float>(config_.icp_max_curvature);
  coarse.max_depth_m = static_cast<float>(config_.icp_depth_limit_m(camera_.depth_noise_per_m()));
  if (config_.per_point_noise != 0) {
    coarse.depth_noise_per_m = static_cast<float>(camera_.depth_noise_per_m());
    coarse.noise_floor_m = static_cast<float>(config_.lateral_sigma_m);
  }
  coarse.prior = prior;  // the fine stage copies it
  coarse.prior_crossover = config_.icp_prior_crossover;
  IcpResult best;
  RefinementStart start = RefinementStart::kNone;
  if (registration.msse_ok) {
    best = icp_.refine(previous_cloud, current_cloud, registration.T_previous_current, coarse);
    if (best.ok) start = RefinementStart::kMsse;
  }
  constexpr double kSameStartM = 0.02;
  constexpr double kSameStartRad = deg_to_rad(1.0);
  const bool distinct_guess =
      !registration.msse_ok ||
      robust::translation_difference_m(registration.T_previous_current, T_previous_current_guess) >
          kSameStartM ||
      robust::rotation_difference_rad(registration.T_previous_current, T_previous_current_guess) >
          kSameStartRad;
  if ((config_.icp_guess_fallback != 0 || !best.ok) && distinct_guess) {
    const IcpResult from_guess =
        icp_.refine(previous_cloud, current_cloud, T_previous_current_guess, coarse);
    if (from_guess.ok) {
      bool take = !best.ok;
      if (!take) {
        // Compare both at one residual scale: the better fit's.
        const auto limit = static_cast<float>(2.5 * std::min(best.rms_m, from_guess.rms_m));
        const int a = icp_.count_within(previous_cloud, current_cloud, best.T_previous_current,
                                        coarse, limit);
        const int b = icp_.count_within(previous_cloud, current_cloud,
                                        from_guess.T_previous_current, coarse, limit);
        take = b > a;
      }
      if (take) {
        best = from_guess;
        start = RefinementStart::kGuess;
      }
    }
  }
  if (start == RefinementStart::kNone || best.inliers < config_.min_inliers) {
    times_.icp_ms = now_ms() - t0;
    return registration;
  }
  if (config_.icp_fine_iterations > 0) {
    IcpConfig fine = coarse;
    fine.max_iterations = config_.icp_fine_iterations;
    fine.max_curvature = static_cast<float>(config_.icp_fine_max_curvature);
    fine.max_points = config_.icp_fine_max_points;
    // Dense source: the current block means against the previous flat centroids' planes.
    const IcpCloud current_blocks{
        {current.block_points.data(), static_cast<std::size_t>(current.block_count)}, {}, {}, {}};
    const IcpResult refined =
        icp_.refine(previous_cloud, current_blocks, best.T_previous_current, fine);
    if (refined.ok && refined.inliers >= config_.min_inliers) best = refined;
  }
  times_.icp_ms = now_ms() - t0;
  registration.refined_from = start;
  registration.icp_inliers = best.inliers;
  registration.icp_rms_m = best.rms_m;
  registration.icp_information = best.information;
  registration.T_previous_current = best.T_previous_current;
  registration.ok = true;
  registration.status = GeometryStatus::kOk;
  return registration;
}

}  // namespace rankslam::geometry
