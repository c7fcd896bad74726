#include "rankslam/slam/registrar.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/stopwatch.hpp"
#include "rankslam/slam/registration_support.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace rankslam::slam {
namespace {

using enum StageTimes::Stage;
using lie::Matrix6d;


// A match "kept its pixel" when it moved less than kStillPx while the prediction moves its
// point by more than kPredictedMovePx; kCameraFixed marks it (in place of its distance).
constexpr float kStillPx = 0.75F;
constexpr float kPredictedMovePx = 3.0F;
constexpr std::uint32_t kCameraFixed = 0xffffffffU;


}  // namespace

Matrix6d cloud_surface_information(const geometry::GeometricFeatures& features, double sigma_m) {
  const auto count = static_cast<std::size_t>(features.cloud_count);
  return (1.0 / (sigma_m * sigma_m)) *
         surface_information({features.cloud_points.data(), count}, {features.cloud_normals.data(), count});
}


Registrar::Registrar(const SlamConfig& config, const camera::DepthCameraModel& camera,
                     RobustEstimator estimator, const Eigen::Isometry3d& T_base_cam, bool differential_drive,
                     parallel::Companion& companion, geometry::GeometricFrontend& geometric)
    : config_(config),
      camera_(camera),
      T_base_cam_(T_base_cam),
      differential_drive_(differential_drive),
      companion_(companion),
      geometric_(geometric),
      estimator_(config, estimator, static_cast<std::size_t>(config.orb_features) * 2 +
                             static_cast<std::size_t>(config.geometry.max_keypoints)) {
  const double prior_rad = deg_to_rad(config_.fused.icp_prior_sigma_deg);
  icp_prior_information_ << Eigen::Vector3d::Constant(1.0 / (prior_rad * prior_rad)),
      Eigen::Vector3d::Constant(1.0 / (config_.fused.icp_prior_sigma_m * config_.fused.icp_prior_sigma_m));
  const auto capacity = static_cast<std::size_t>(config.orb_features) * 2;
  matches_.reserve(capacity);
  matcher_.reserve(capacity);
  const std::size_t correspondence_capacity =
      capacity + static_cast<std::size_t>(config.geometry.max_keypoints);
  source_points_.reserve(correspondence_capacity);
  target_points_.reserve(correspondence_capacity);
  correspondence_sigma_m_.reserve(correspondence_capacity);
  kind_weights_.reserve(correspondence_capacity);
}

Eigen::Vector3f Registrar::rolling_shutter_corrected(const Eigen::Vector3f& point, double row,
                                                    const Velocity& velocity) const {
  return slam::rolling_shutter_corrected(point, row, camera_.height(), config_.rolling_shutter_readout_ms * 1e-3, velocity);
}

MotionEstimate Registrar::register_frames(const PhotometricFeatures& target, const Velocity& target_velocity,
                                         const PhotometricFeatures& current, const Velocity& current_velocity,
                                         FrameResult& result, const Eigen::Isometry3d& predicted,
                                         const Eigen::Isometry3d& at_rest,
                                         const geometry::GeometricFeatures* target_geometric,
                                         const geometry::GeometricFeatures* current_geometric, bool refine) {
  auto stage_start = SteadyClock::now();
  const auto match_photometric = [&] {
    matcher_.match(target.descriptors, current.descriptors, config_.max_hamming_distance, matches_);
  };
  // Fused: the ORB matches on the companion thread while the SHOT matches take the team.
  const bool fused = target_geometric != nullptr && current_geometric != nullptr;
  int geometric_count = 0;
  if (fused) {
    companion_.launch(match_photometric);
    if (geometric_.correspondences(*target_geometric, *current_geometric, geometric_matches_) ==
        geometry::GeometryStatus::kOk) {
      geometric_count = geometric_matches_.count;
    }
    companion_.wait();
  } else {
    match_photometric();
  }
  const auto corrected = [&](const PhotometricFeatures& features, std::uint32_t i, const Velocity& velocity) {
    return rolling_shutter_corrected(features.points_cam[i], features.keypoints[i].pt.y, velocity);
  };
  source_points_.clear();
  target_points_.clear();
  correspondence_sigma_m_.clear();
  // IR: the projector's speckle pattern moves with the camera (only depth parallax shifts it),
  // and what the pre-processing leaves of it gives features that keep their pixel while the
  // camera moves. Such matches pull the estimate towards no motion; they are dropped unless they
  // are the majority (then the camera did stop). Colour images have no such pattern, and there
  // the same test only removes true matches whenever the prediction is off, so it is not applied.
  bool drop_camera_fixed = false;
  if (current.source == ImageSource::kInfrared && target.source == ImageSource::kInfrared) {
    const Eigen::Isometry3f T_current_target = predicted.inverse().cast<float>();
    const auto fx = static_cast<float>(camera_.calibration().fx);
    const auto fy = static_cast<float>(camera_.calibration().fy);
    int camera_fixed = 0;
    for (FeatureMatch& match : matches_) {
      const cv::Point2f& seen_before = target.keypoints[match.source].pt;
      const cv::Point2f& seen_now = current.keypoints[match.target].pt;
      const float moved_px = std::hypot(seen_now.x - seen_before.x, seen_now.y - seen_before.y);
      const Eigen::Vector3f& p = target.points_cam[match.source];
      const Eigen::Vector3f q = T_current_target * p;
      const float predicted_px =
          q.z() > 0.0F ? std::hypot(fx * (q.x() / q.z() - p.x() / p.z()), fy * (q.y() / q.z() - p.y() / p.z())) : 0.0F;
      if (moved_px < kStillPx && predicted_px > kPredictedMovePx) {
        match.distance = kCameraFixed;
        ++camera_fixed;
      }
    }
    drop_camera_fixed = 2 * camera_fixed < static_cast<int>(matches_.size());
  }
  for (const FeatureMatch& match : matches_) {
    if (drop_camera_fixed && match.distance == kCameraFixed) continue;
    source_points_.push_back(corrected(current, match.target, current_velocity));
    target_points_.push_back(corrected(target, match.source, target_velocity));
    const double sigma_source = current.sigma_m[match.target];
    const double sigma_target = target.sigma_m[match.source];
    correspondence_sigma_m_.push_back(std::sqrt(sigma_source * sigma_source + sigma_target * sigma_target));
  }
  result.matches = static_cast<int>(source_points_.size());
  result.times.ms[kMatching] += elapsed_ms(stage_start);
  if (fused) {
    return fused_estimate(*target_geometric, target_velocity, *current_geometric, current_velocity, geometric_count,
                          result, predicted, at_rest, refine);
  }

  stage_start = SteadyClock::now();
  // Per-correspondence noise (ranking and refit weights): a keypoint's depth error grows with z².
  MotionEstimate estimate = estimator_.estimate(source_points_, target_points_, correspondence_sigma_m_, &predicted);
  result.inliers = estimate.inliers;
  result.noise_scale = estimate.noise_scale;
  result.times.ms[kEstimation] += elapsed_ms(stage_start);
  return estimate;
}

MotionEstimate Registrar::fused_estimate(const geometry::GeometricFeatures& target_geometric,
                                        const Velocity& target_velocity,
                                        const geometry::GeometricFeatures& current_geometric,
                                        const Velocity& current_velocity, int geometric_count,
                                        FrameResult& result, const Eigen::Isometry3d& predicted,
                                        const Eigen::Isometry3d& at_rest, bool refine) {
  auto stage_start = SteadyClock::now();
  const auto photometric_count = static_cast<int>(source_points_.size());
  // 1. Each kind alone: its inlier ratio says how well it fits this scene.
  constexpr int kMinimalSample = 3;
  MotionEstimate photometric;
  if (photometric_count > kMinimalSample) {
    photometric = estimator_.estimate(source_points_, target_points_, correspondence_sigma_m_, &predicted);
  }
  const auto photometric_end = static_cast<std::size_t>(photometric_count);
  // A geometric keypoint is a voxel centroid: where the leaf's cell boundaries fall moves it by
  // up to a leaf between frames, far more than the depth noise of its points.
  const double quantisation = config_.fused.geometric_leaf_sigma;
  const double target_leaf = target_geometric.voxel_leaf_m;
  const double current_leaf = current_geometric.voxel_leaf_m;
  const double quantisation_sq =
      quantisation * quantisation * (target_leaf * target_leaf + current_leaf * current_leaf);
  // A keypoint's depth was read in the row it projects to: the same rolling-shutter correction.
  const double fy = camera_.calibration().fy;
  const double cy = camera_.calibration().cy;
  const auto corrected = [&](const Eigen::Vector3d& point, const Velocity& velocity) {
    const double row = point.z() > 0.0 ? fy * point.y() / point.z() + cy : cy;
    return rolling_shutter_corrected(point.cast<float>(), row, velocity);
  };
  for (int i = 0; i < geometric_count; ++i) {
    source_points_.push_back(corrected(geometric_matches_.current.col(i), current_velocity));
    target_points_.push_back(corrected(geometric_matches_.previous.col(i), target_velocity));
    const double sigma = geometric_matches_.sigma_m[static_cast<std::size_t>(i)];
    correspondence_sigma_m_.push_back(std::sqrt(sigma * sigma + quantisation_sq));
  }
  const std::span<const Eigen::Vector3f> geometric_source(source_points_.data() + photometric_end,
                                                          static_cast<std::size_t>(geometric_count));
  const std::span<const Eigen::Vector3f> geometric_target(target_points_.data() + photometric_end,
                                                          static_cast<std::size_t>(geometric_count));
  const std::span<const double> geometric_sigma(correspondence_sigma_m_.data() + photometric_end,
                                                static_cast<std::size_t>(geometric_count));
  MotionEstimate geometric;
  if (geometric_count > kMinimalSample) {
    geometric = estimator_.estimate(geometric_source, geometric_target, geometric_sigma, &predicted);
  }
  const int photometric_inliers = photometric.ok ? photometric.inliers : 0;
  const int geometric_inliers = geometric.ok ? geometric.inliers : 0;
  result.photometric_matches = photometric_count;
  result.photometric_inliers = photometric_inliers;
  result.geometric_matches = geometric_count;
  result.geometric_inliers = geometric_inliers;
  result.matches = photometric_count + geometric_count;

  // 2. One kind without inliers: the other carries the estimate alone.
  MotionEstimate fused;
  if (photometric_inliers == 0 || geometric_inliers == 0) {
    fused = photometric_inliers > 0 ? photometric : geometric;
    result.photometric_weight = photometric_inliers > 0 ? 1.0 : 0.0;
    if (!fused.ok && fused.failure_reason.empty()) fused.failure_reason = "no matches of either kind";
  } else {
    // 3. W_P = (k_P / n_P) / (k_G / n_G), W_G = 1 / W_P; one weighted MSSE over both sets.
    const double photometric_weight =
        config_.fused.inlier_ratio_weights == 0
            ? 1.0
            : (static_cast<double>(photometric_inliers) / photometric_count) /
                  (static_cast<double>(geometric_inliers) / geometric_count);
    kind_weights_.assign(static_cast<std::size_t>(photometric_count), photometric_weight);
    kind_weights_.insert(kind_weights_.end(), static_cast<std::size_t>(geometric_count), 1.0 / photometric_weight);
    fused = estimator_.estimate(source_points_, target_points_, correspondence_sigma_m_, &predicted, kind_weights_);
    result.photometric_weight = photometric_weight;
  }
  result.inliers = fused.ok ? fused.inliers : 0;
  result.noise_scale = fused.noise_scale;
  result.times.ms[kEstimation] += elapsed_ms(stage_start);
  // Where the photometric kind is weak (plain surfaces), the geometric front-end's ICP refines
  // the estimate on the dense clouds; where it is strong, a refinement that moves the estimate
  // more than a feature registration's error is ICP sliding along a plane and is dropped.
  // Where the view fixes only part of the motion, the ICP holds a prior in the rest: the feature
  // estimate when it is one (see SlamConfig::fused_max_noise_scale), else the previous pose. An
  // estimate that is no registration neither seeds the ICP (a corridor's end wall registered
  // turned around, and ICP from there stayed turned) nor holds it.
  last_photometric_inliers_ = photometric_inliers;
  last_photometric_rotation_sigma_deg_ =
      photometric_rotation_sigma_deg(photometric, static_cast<std::size_t>(photometric_count));
  if (refine && photometric_needs_refinement(config_.fused.icp_above_rotation_sigma_deg)) {
    stage_start = SteadyClock::now();
    const std::span<const Eigen::Vector3f> all_source(source_points_);
    const std::span<const Eigen::Vector3f> all_target(target_points_);
    const std::span<const double> all_sigma(correspondence_sigma_m_);
    const bool shaped = photometric_inliers >= config_.min_inliers ||
                        (geometric.ok && inlier_thickness_m(geometric.T_target_source, geometric_source, geometric_target,
                                                            geometric_sigma) >= config_.fused.min_geometric_thickness_m);
    const bool registered = fused.ok && fused.inliers >= config_.min_inliers &&
                            fused.noise_scale <= config_.fused.max_noise_scale && shaped;
    const Matrix6d feature_information =
        registered ? correspondence_information(fused.T_target_source, all_source, all_target, all_sigma) : Matrix6d::Zero();
    const geometry::IcpPrior prior = fused_icp_prior(at_rest, predicted, fused, registered, feature_information);
    const geometry::FrameRegistration refined = geometric_.register_frames(
        target_geometric, current_geometric, registered ? fused.T_target_source : predicted, prior);
    if (refined.ok && refined.refined_from != geometry::RefinementStart::kNone) {
      fused.ok = true;
      fused.T_target_source = refined.T_previous_current;
      fused.inliers = std::max(fused.inliers, refined.inliers);
      fused.icp_inliers = refined.icp_inliers;
      // The registration's information (and so its graph edge's) is what fixed the estimate: the
      // surfaces, and in what they leave free the ICP's prior. The base's drivable step carries
      // the feature estimate's information too; the prior is on a motion applied on the left,
      // the edge's on the right. Counted as the surfaces and features alone, key-frame edges
      // within a turn were far too certain along the view, and a loop closure's correction went
      // into the turns.
      fused.information = cloud_surface_information(current_geometric, config_.graph.icp_sigma_m);
      if (icp_prior_is_drivable_step()) {
        const Matrix6d to_left = lie::adjoint(fused.T_target_source);
        fused.information += to_left.transpose() * prior.information * to_left;
      } else {
        fused.information += feature_information;
      }
      result.inliers = fused.inliers;
      result.icp_refined = true;
    }
    result.times.ms[kIcp] += elapsed_ms(stage_start);
  }
  return fused;
}

double Registrar::photometric_rotation_sigma_deg(const MotionEstimate& photometric, std::size_t photometric_count) const {
  if (!photometric.ok) return std::numeric_limits<double>::infinity();
  const std::span<const Eigen::Vector3f> source(source_points_.data(), photometric_count);
  const std::span<const Eigen::Vector3f> target(target_points_.data(), photometric_count);
  const std::span<const double> sigma(correspondence_sigma_m_.data(), photometric_count);
  const Matrix6d information = correspondence_information(photometric.T_target_source, source, target, sigma) /
                               std::max(1.0, photometric.noise_scale * photometric.noise_scale);
  return rad_to_deg(rotation_sigma_rad(information));
}

bool Registrar::photometric_needs_refinement(double above_rotation_sigma_deg) const {
  if (config_.fused.icp_below_photometric_inliers > 0 &&
      last_photometric_inliers_ < config_.fused.icp_below_photometric_inliers) {
    return true;
  }
  return above_rotation_sigma_deg > 0.0 && !(last_photometric_rotation_sigma_deg_ <= above_rotation_sigma_deg);
}

geometry::IcpPrior Registrar::fused_icp_prior(const Eigen::Isometry3d& at_rest, const Eigen::Isometry3d& predicted,
                                             const MotionEstimate& feature, bool registered,
                                             const Matrix6d& feature_information) const {
  geometry::IcpPrior prior;
  if (!icp_prior_is_drivable_step()) {
    prior.T_previous_current = registered ? feature.T_target_source : at_rest;
    // At rest, the step is the robot base's (through the camera mount): a base turning in place
    // swings the camera on its lever arm, and its turns came out short while the camera itself
    // was held still. A feature estimate's error is the camera's. Without a mount (identity) the
    // two are the same.
    prior.information = step_prior_information(prior.T_previous_current,
                                               registered ? Eigen::Isometry3d::Identity() : T_base_cam_,
                                               icp_prior_information_);
    return prior;
  }
  // The base's drivable step from the previous frame at its predicted speed and turn rate, held
  // with the base's per-frame strength; a feature registration moves it by its own information
  // (less where its inliers fit worse than their noise).
  const Matrix6d to_base = lie::adjoint(T_base_cam_);
  MotionBelief belief;
  belief.mean = at_rest * drivable_step(at_rest.inverse() * predicted, T_base_cam_);
  belief.information = to_base.transpose() * icp_prior_information_.asDiagonal() * to_base;
  if (registered) {
    MotionBelief measured;
    measured.mean = feature.T_target_source;
    measured.information = feature_information / std::max(1.0, feature.noise_scale * feature.noise_scale);
    belief = combine(belief, measured);
  }
  prior.T_previous_current = belief.mean;
  prior.information = prior_information_on_target(belief.mean, belief.information);
  return prior;
}

}  // namespace rankslam::slam

namespace rankslam::slam {

StoredRefinement refine_on_stored_cloud(const Registrar& registrar, geometry::GeometricFrontend& geometric,
                                        const SlamConfig& config, double above_rotation_sigma_deg,
                                        const geometry::GeometricFeatures& stored,
                                        const geometry::GeometricFeatures& current, Eigen::Isometry3d& T_stored_current) {
  if (!registrar.photometric_needs_refinement(above_rotation_sigma_deg)) return StoredRefinement::kNotNeeded;
  if (stored.cloud_count < 3 || current.cloud_count < 3) return StoredRefinement::kFailed;
  geometry::IcpPrior feature_prior;
  feature_prior.T_previous_current = T_stored_current;
  feature_prior.information =
      step_prior_information(T_stored_current, Eigen::Isometry3d::Identity(), registrar.icp_prior_information());
  const geometry::FrameRegistration refined = geometric.register_frames(stored, current, T_stored_current, feature_prior);
  if (!refined.ok || refined.refined_from == geometry::RefinementStart::kNone ||
      refined.icp_inliers < config.min_icp_inliers) {
    return StoredRefinement::kFailed;
  }
  // Refinement that could not fix what the features left loose keeps their error.
  if (least_information_ratio(refined.icp_information, feature_prior.information) < config.loop.icp_min_information_ratio) {
    return StoredRefinement::kFailed;
  }
  T_stored_current = refined.T_previous_current;
  return StoredRefinement::kRefined;
}

}  // namespace rankslam::slam
