#include "rankslam/slam/slam_loop.hpp"

#include "rankslam/slam/registration_support.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rankslam::slam {
namespace {

using Clock = std::chrono::steady_clock;

double elapsed_ms(Clock::time_point since) {
  return std::chrono::duration<double, std::milli>(Clock::now() - since).count();
}

double rotation_deg(const Eigen::Isometry3d& motion) {
  return Eigen::AngleAxisd(motion.rotation()).angle() * 180.0 / M_PI;
}

enum Stage : std::size_t { kPreprocess, kFeatures, kMatching, kEstimation, kIcp, kMapping };

// The colour image must brighten to this multiple of the switch threshold before features
// return to it: a scene hovering at the threshold would otherwise flip image kinds every few
// frames, and each switch costs a second feature extraction.
constexpr double kColourReturnFactor = 1.25;

// A match "kept its pixel" when it moved less than kStillPx while the prediction moves its
// point by more than kPredictedMovePx; kCameraFixed marks it (in place of its distance).
constexpr float kStillPx = 0.75F;
constexpr float kPredictedMovePx = 3.0F;
constexpr std::uint32_t kCameraFixed = 0xffffffffU;

IcpSettings icp_settings(const SlamConfig& config) {
  IcpSettings settings;
  settings.mode = config.icp_mode;
  settings.max_depth_m = config.icp_max_depth_m;
  settings.voxel_m = config.icp_voxel_m;
  settings.pixel_stride = config.icp_pixel_stride;
  settings.max_correspondence_m = config.icp_max_correspondence_m;
  settings.max_iterations = config.icp_max_iterations;
  settings.max_source_points = config.icp_max_source_points;
  return settings;
}

Eigen::Matrix<double, 6, 1> velocity_of(const Eigen::Isometry3d& motion, double dt_s) {
  const Eigen::AngleAxisd rotation(motion.rotation());
  Eigen::Matrix<double, 6, 1> velocity;
  velocity.head<3>() = rotation.angle() * rotation.axis() / dt_s;
  velocity.tail<3>() = motion.translation() / dt_s;
  return velocity;
}

// Composing thousands of motions lets rounding errors pull a rotation matrix away from
// orthonormal, and a scaled rotation makes poses grow geometrically. Renormalising through the
// quaternion keeps every pose a rigid motion.
Eigen::Isometry3d rigid(const Eigen::Isometry3d& pose) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::Quaterniond(pose.rotation()).normalized().toRotationMatrix();
  out.translation() = pose.translation();
  return out;
}

bool valid_image(const cv::Mat& image, int type, int width, int height) {
  return image.type() == type && image.cols == width && image.rows == height;
}

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// ξ = (rotation vector, translation) with `motion` = exp(ξ), to first order in the translation:
// the residuals compared with the prior are small.
Vector6d log_motion(const Eigen::Isometry3d& motion) {
  const Eigen::AngleAxisd rotation(motion.rotation());
  Vector6d xi;
  xi.head<3>() = rotation.angle() * rotation.axis();
  xi.tail<3>() = motion.translation();
  return xi;
}

double mahalanobis_sq(const Vector6d& residual, const Matrix6d& covariance) {
  const Eigen::LDLT<Matrix6d> factor(covariance);
  if (factor.info() != Eigen::Success) return std::numeric_limits<double>::infinity();
  return residual.dot(factor.solve(residual));
}

// Inverse of a symmetric positive-definite 6×6 (an information or covariance matrix), symmetric
// to the last bit so that it can be inverted back and added up.
Matrix6d symmetric_inverse(const Matrix6d& matrix) {
  const Matrix6d inverse = matrix.llt().solve(Matrix6d::Identity());
  return 0.5 * (inverse + inverse.transpose());
}

// The point-to-plane information of a frame's sampled cloud at `sigma_m` per fully constraining
// direction: what an ICP-refined registration (sequential or loop closure) measured.
Matrix6d cloud_surface_information(const geometry::GeometricFeatures& features, double sigma_m) {
  const auto count = static_cast<std::size_t>(features.cloud_count);
  return (1.0 / (sigma_m * sigma_m)) *
         surface_information({features.cloud_points.data(), count}, {features.cloud_normals.data(), count});
}

}  // namespace

MotionPrior camera_motion_prior(double x_m, double y_m, double yaw_rad, const Eigen::Matrix3d& planar_covariance,
                                const Eigen::Isometry3d& T_base_cam) {
  Eigen::Isometry3d T_base_previous_base_current = Eigen::Isometry3d::Identity();
  T_base_previous_base_current.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T_base_previous_base_current.translation() = Eigen::Vector3d(x_m, y_m, 0.0);
  const Eigen::Isometry3d T_cam_base = T_base_cam.inverse();
  MotionPrior prior;
  prior.T_previous_current = rigid(T_cam_base * T_base_previous_base_current * T_base_cam);

  // A change (δx, δy, δyaw) of the planar motion D is, to first order, D' = exp(ξ_base)·D with
  // ω = δyaw·z and v = (δx, δy, 0) − δyaw·z × t_D in the previous base frame; conjugating with
  // T_cam_base carries ξ into the previous camera frame (the adjoint: ω_c = R ω, v_c = R v + t × R ω).
  Eigen::Matrix<double, 6, 3> base_jacobian = Eigen::Matrix<double, 6, 3>::Zero();
  base_jacobian(2, 2) = 1.0;
  base_jacobian(3, 0) = 1.0;
  base_jacobian(4, 1) = 1.0;
  base_jacobian(3, 2) = y_m;
  base_jacobian(4, 2) = -x_m;
  const Eigen::Matrix<double, 6, 3> jacobian = adjoint(T_cam_base) * base_jacobian;
  prior.covariance = jacobian * planar_covariance * jacobian.transpose();
  return prior;
}

SlamLoop::SlamLoop(const SlamConfig& config, const hal::Calibration& calibration)
    : config_(config),
      camera_(calibration.rgb, calibration.depth_scale),
      T_base_cam_(calibration.rgb.T_base_cam),
      differential_drive_(calibration.wheels.has_value()),
      orb_(config_, camera_),
      infrared_orb_(config_, camera_, config_.ir_orb_fast_threshold),
      estimator_(config_, static_cast<std::size_t>(config.orb_features) * 2 +
                              static_cast<std::size_t>(geometry::FrontendCapacities{}.max_keypoints)),
      map_(config.map_voxel_m, static_cast<std::size_t>(config.map_max_points)),
      infrared_filter_(camera_.width(), camera_.height()),
      icp_(icp_settings(config_), camera_),
      map_sampler_(static_cast<std::mt19937::result_type>(config.seed)),
      keyframe_store_(config.keyframe_capacity,
                      config.mode == Mode::kGeometric ? 0 : static_cast<std::size_t>(config.orb_features) * 2,
                      config.mode == Mode::kGeometric || config.mode == Mode::kFused ? config.geometry.max_keypoints : 0,
                      config.mode == Mode::kFused ? config.keyframe_cloud_points : 0,
                      config.map_points_per_keyframe),
      loop_threshold_(config.loop_initial_threshold, config.loop_threshold_deviations) {
  // Room for a sequential edge per key-frame and several loop closures each.
  constexpr int kEdgesPerKeyframe = 8;
  const graph::Capacity graph_capacity{config_.keyframe_capacity, config_.keyframe_capacity * kEdgesPerKeyframe};
  for (const std::string& error :
       {graph_.configure(graph_capacity), optimizer_.configure(graph_capacity), optimized_.configure(graph_capacity)}) {
    if (!error.empty()) throw std::invalid_argument(error);
  }
  loop_candidates_.reserve(static_cast<std::size_t>(config_.keyframe_capacity));
  // One key-frame adds at most loop_max_candidates closures; the log holds many key-frames' worth.
  closure_log_.resize(static_cast<std::size_t>(std::max(kClosureLogMinCapacity, 4 * config_.loop_max_candidates)));
  const double prior_rad = config_.fused_icp_prior_sigma_deg * M_PI / 180.0;
  icp_prior_information_ << Eigen::Vector3d::Constant(1.0 / (prior_rad * prior_rad)),
      Eigen::Vector3d::Constant(1.0 / (config_.fused_icp_prior_sigma_m * config_.fused_icp_prior_sigma_m));
  wheel_window_.resize(static_cast<std::size_t>(std::max(1, config_.wheel_gate_window_frames)));
  const auto capacity = static_cast<std::size_t>(config.orb_features) * 2;
  for (auto& tracked : frames_) {
    tracked.features.reserve(capacity);
    if (config_.icp_mode != IcpMode::kOff) {
      tracked.cloud.points.reserve(icp_.cloud_capacity());
      tracked.cloud.normals.reserve(icp_.cloud_capacity());
    }
  }
  bridge_.reserve(capacity);
  matches_.reserve(capacity);
  matcher_.reserve(capacity);
  const std::size_t correspondence_capacity =
      capacity + static_cast<std::size_t>(geometry::FrontendCapacities{}.max_keypoints);
  source_points_.reserve(correspondence_capacity);
  target_points_.reserve(correspondence_capacity);
  correspondence_sigma_m_.reserve(correspondence_capacity);
  kind_weights_.reserve(correspondence_capacity);
  gray_.create(camera_.height(), camera_.width(), CV_8UC1);
  infrared_.create(camera_.height(), camera_.width(), CV_8UC1);
  // OpenCV sets up its parallel framework (worker threads, thread-local storage) in the first
  // parallel call of the process and thread, which would otherwise be the first frame's cvtColor.
  const auto warm_up_opencv = [this] {
    cv::cvtColor(cv::Mat(camera_.height(), camera_.width(), CV_8UC3, cv::Scalar::all(0)), gray_, cv::COLOR_BGR2GRAY);
  };
  warm_up_opencv();
  if (const std::string error = team_.start(config_.threads); !error.empty()) {
    throw std::invalid_argument("slam.threads: " + error);
  }
  estimator_.share_with(&team_);
  if (config_.mode == Mode::kGeometric || config_.mode == Mode::kFused) {
    if (const std::string error = geometric_.configure(camera_, config_.geometry, {}, &team_); !error.empty()) {
      throw std::invalid_argument(error);
    }
  }
  if (config_.mode == Mode::kGeometric) {
    for (auto& features : geometric_features_) features = geometric_.make_features();
  }
  if (config_.mode == Mode::kFused) {
    for (auto& tracked : frames_) tracked.geometric = geometric_.make_features();
    if (config_.loop_candidates_per_frame > 0 && config_.loop_candidates_per_frame < config_.loop_max_candidates) {
      loop_search_copy_ = geometric_.make_features();  // a search may carry over into later frames
    }
    geometric_matches_ = geometric_.make_correspondences();
    if (config_.threads > 1) {
      if (const std::string error = companion_.start(); !error.empty()) {
        throw std::invalid_argument("slam.threads: " + error);
      }
      companion_.launch(warm_up_opencv);  // the companion is a thread of its own for OpenCV too
      companion_.wait();
    }
  }
}

ImageSource SlamLoop::choose_source(const hal::RgbdFrame& frame) {
  const int width = camera_.width();
  const int height = camera_.height();
  gray_valid_ = valid_image(frame.rgb, CV_8UC3, width, height);
  if (gray_valid_) cv::cvtColor(frame.rgb, gray_, cv::COLOR_BGR2GRAY);
  infrared_valid_ = false;  // filtered only when needed
  const bool ir_present =
      valid_image(frame.ir, CV_8UC1, width, height) || valid_image(frame.ir, CV_16UC1, width, height);
  if (!gray_valid_) {
    infrared_active_ = ir_present;
  } else if (!ir_present || config_.ir_switch_brightness <= 0.0) {
    infrared_active_ = false;
  } else {
    const double threshold = infrared_active_ ? config_.ir_switch_brightness * kColourReturnFactor
                                              : config_.ir_switch_brightness;
    infrared_active_ = mean_brightness(gray_) < threshold;
  }
  return infrared_active_ ? ImageSource::kInfrared : ImageSource::kColour;
}

const cv::Mat* SlamLoop::feature_image(const hal::RgbdFrame& frame, ImageSource source) {
  if (source == ImageSource::kColour) return gray_valid_ ? &gray_ : nullptr;
  if (!infrared_valid_) infrared_valid_ = infrared_filter_.apply(frame.ir, infrared_);
  return infrared_valid_ ? &infrared_ : nullptr;
}

Eigen::Vector3f SlamLoop::rolling_shutter_corrected(const Eigen::Vector3f& point, double row,
                                                    const Velocity& velocity) const {
  const double readout_s = config_.rolling_shutter_readout_ms * 1e-3;
  if (readout_s == 0.0) return point;
  // Rolling shutter: row y was exposed (y/h − ½)·readout after the frame's mid-exposure time.
  // Moving its point by the camera's velocity over that time (first order) expresses it in the
  // mid-exposure camera frame.
  const double dt_s = (row / static_cast<double>(camera_.height()) - 0.5) * readout_s;
  const Eigen::Vector3d p = point.cast<double>();
  return Eigen::Vector3f((p + dt_s * (velocity.head<3>().cross(p) + velocity.tail<3>())).cast<float>());
}

MotionEstimate SlamLoop::register_frames(const PhotometricFeatures& target, const Velocity& target_velocity,
                                         const PhotometricFeatures& current, const Velocity& current_velocity,
                                         FrameResult& result, const Eigen::Isometry3d& predicted,
                                         const Eigen::Isometry3d& at_rest,
                                         const geometry::GeometricFeatures* target_geometric,
                                         const geometry::GeometricFeatures* current_geometric, bool refine) {
  auto stage_start = Clock::now();
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
  // are the majority (then the camera did stop). Simulated dark office, seeds 1-6: ATE
  // 0.015-0.025 m with, 0.025-0.038 m without. Colour images have no such pattern, and there the
  // same test only removes true matches whenever the prediction is off (fr1_rpy_head mean ATE
  // 0.028 -> 0.030 m), so it is not applied.
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

  stage_start = Clock::now();
  // Per-correspondence noise (ranking and refit weights): fr1_rpy_head ATE over seeds 1-6, mean
  // 0.0281 m with it, 0.0575 m without.
  MotionEstimate estimate = estimator_.estimate(source_points_, target_points_, correspondence_sigma_m_, &predicted);
  result.inliers = estimate.inliers;
  result.noise_scale = estimate.noise_scale;
  result.times.ms[kEstimation] += elapsed_ms(stage_start);
  return estimate;
}

MotionEstimate SlamLoop::fused_estimate(const geometry::GeometricFeatures& target_geometric,
                                        const Velocity& target_velocity,
                                        const geometry::GeometricFeatures& current_geometric,
                                        const Velocity& current_velocity, int geometric_count,
                                        FrameResult& result, const Eigen::Isometry3d& predicted,
                                        const Eigen::Isometry3d& at_rest, bool refine) {
  auto stage_start = Clock::now();
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
  const double quantisation = config_.fused_geometric_leaf_sigma;
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
    const double photometric_weight = (static_cast<double>(photometric_inliers) / photometric_count) /
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
  // turned by 180 deg, and ICP from there stayed turned) nor holds it.
  last_photometric_inliers_ = photometric_inliers;
  last_photometric_rotation_sigma_deg_ =
      photometric_rotation_sigma_deg(photometric, static_cast<std::size_t>(photometric_count));
  if (refine && photometric_needs_refinement(config_.fused_icp_above_rotation_sigma_deg)) {
    stage_start = Clock::now();
    const std::span<const Eigen::Vector3f> all_source(source_points_);
    const std::span<const Eigen::Vector3f> all_target(target_points_);
    const std::span<const double> all_sigma(correspondence_sigma_m_);
    const bool shaped = photometric_inliers >= config_.min_inliers ||
                        (geometric.ok && inlier_thickness_m(geometric.T_target_source, geometric_source, geometric_target,
                                                            geometric_sigma) >= config_.fused_min_geometric_thickness_m);
    const bool registered = fused.ok && fused.inliers >= config_.min_inliers &&
                            fused.noise_scale <= config_.fused_max_noise_scale && shaped;
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
      // within a turn held up to 0.85 m of error along the view (corridor loop, recording seed
      // 3), and a loop closure's correction went into the turns (recording seed 1 with loop
      // closure: ATE 0.0435 m that way, 0.0330 m with the prior).
      fused.information = cloud_surface_information(current_geometric, config_.graph_icp_sigma_m);
      if (icp_prior_is_drivable_step()) {
        const Matrix6d to_left = adjoint(fused.T_target_source);
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

double SlamLoop::photometric_rotation_sigma_deg(const MotionEstimate& photometric, std::size_t photometric_count) const {
  if (!photometric.ok) return std::numeric_limits<double>::infinity();
  const std::span<const Eigen::Vector3f> source(source_points_.data(), photometric_count);
  const std::span<const Eigen::Vector3f> target(target_points_.data(), photometric_count);
  const std::span<const double> sigma(correspondence_sigma_m_.data(), photometric_count);
  const Matrix6d information = correspondence_information(photometric.T_target_source, source, target, sigma) /
                               std::max(1.0, photometric.noise_scale * photometric.noise_scale);
  return rotation_sigma_rad(information) * 180.0 / M_PI;
}

bool SlamLoop::photometric_needs_refinement(double above_rotation_sigma_deg) const {
  if (config_.fused_icp_below_photometric_inliers > 0 &&
      last_photometric_inliers_ < config_.fused_icp_below_photometric_inliers) {
    return true;
  }
  return above_rotation_sigma_deg > 0.0 && !(last_photometric_rotation_sigma_deg_ <= above_rotation_sigma_deg);
}

geometry::IcpPrior SlamLoop::fused_icp_prior(const Eigen::Isometry3d& at_rest, const Eigen::Isometry3d& predicted,
                                             const MotionEstimate& feature, bool registered,
                                             const Matrix6d& feature_information) const {
  geometry::IcpPrior prior;
  if (!icp_prior_is_drivable_step()) {
    prior.T_previous_current = registered ? feature.T_target_source : at_rest;
    // At rest, the step is the robot base's (through the camera mount): a base turning in place
    // swings the camera on its lever arm, 15 cm on the corridor robot, whose turns came out
    // 30-45 % short while the camera itself was held still. A feature estimate's error is the
    // camera's. Without a mount (identity) the two are the same.
    prior.information = step_prior_information(prior.T_previous_current,
                                               registered ? Eigen::Isometry3d::Identity() : T_base_cam_,
                                               icp_prior_information_);
    return prior;
  }
  // The base's drivable step from the previous frame at its predicted speed and turn rate, held
  // with the base's per-frame strength; a feature registration moves it by its own information
  // (less where its inliers fit worse than their noise).
  const Matrix6d to_base = adjoint(T_base_cam_);
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

bool SlamLoop::accept(const MotionEstimate& estimate, const Eigen::Isometry3d& T_world_target,
                      const Eigen::Isometry3d& T_world_previous, const Eigen::Isometry3d& predicted_step,
                      Eigen::Isometry3d& T_world_current, std::string_view& reason, bool resuming) const {
  std::string_view why;
  if (!estimate.ok) {
    why = estimate.failure_reason;
  } else if (estimate.inliers < config_.min_inliers && estimate.icp_inliers < config_.min_icp_inliers) {
    why = "too few inliers";
  } else if (resuming && estimate.inliers < config_.reference_min_overlap * reference_inliers_) {
    why = "too few inliers to resume tracking";
  } else if (!estimate.T_target_source.matrix().allFinite()) {
    why = "non-finite estimate";
  } else {
    const Eigen::Isometry3d T_world_candidate = T_world_target * estimate.T_target_source;
    if (resuming) {
      // The prediction is an extrapolation; the pose must still be one the camera can have
      // reached since its last measured pose: the prediction's gate, widened by one gate per
      // frame since then. (Without it, a plain corridor's end wall registered turned by 179 deg
      // after a single failed frame.)
      const Eigen::Isometry3d since_tracked = T_world_last_tracked_.inverse() * T_world_candidate;
      const double frames_since_tracked = failed_in_a_row_ + 1.0;
      if (since_tracked.translation().norm() > frames_since_tracked * config_.max_deviation_translation_m ||
          rotation_deg(since_tracked) > frames_since_tracked * config_.max_deviation_rotation_deg) {
        why = "motion since the last tracked frame far from any the camera can have made";
      }
    } else {
      const Eigen::Isometry3d step = T_world_previous.inverse() * T_world_candidate;
      const Eigen::Isometry3d deviation = predicted_step.inverse() * step;
      if (step.translation().norm() > config_.max_step_translation_m ||
          rotation_deg(step) > config_.max_step_rotation_deg) {
        why = "implausible frame-to-frame motion";
      } else if (deviation.translation().norm() > config_.max_deviation_translation_m ||
                 rotation_deg(deviation) > config_.max_deviation_rotation_deg) {
        why = "motion far from the prediction";
      }
    }
    if (why.empty()) {
      T_world_current = T_world_candidate;
      return true;
    }
  }
  if (reason.empty()) reason = why;  // the first attempt's reason is the telling one
  return false;
}

void SlamLoop::refine_with_icp(const TrackedFrame& target, const TrackedFrame& current, FrameResult& result) {
  const auto stage_start = Clock::now();
  icp_.set_target(target.cloud, target.id);
  const Eigen::Isometry3d T_target_current = target.T_world_cam.inverse() * result.T_world_cam;
  const IcpResult refined = icp_.align(current.cloud, T_target_current);
  if (refined.ok) {
    // A large correction means ICP slid along a plane or into another minimum rather than
    // refining the feature estimate.
    const Eigen::Isometry3d correction = T_target_current.inverse() * refined.T_target_source;
    if (correction.translation().norm() <= config_.icp_max_correction_m &&
        rotation_deg(correction) <= config_.icp_max_correction_deg) {
      result.T_world_cam = target.T_world_cam * refined.T_target_source;
      result.icp_refined = true;
    }
  }
  result.times.ms[kIcp] += elapsed_ms(stage_start);
}

bool SlamLoop::check_against_wheels(const MotionPrior& prior, const Eigen::Isometry3d& T_world_previous, int inliers,
                                    FrameResult& result) {
  WheelCheck& check = result.wheels;
  check.compared = true;
  const Eigen::Isometry3d registered = T_world_previous.inverse() * result.T_world_cam;
  const Vector6d residual = log_motion(registered * prior.T_previous_current.inverse());
  const double sigma_rad = config_.wheel_vision_sigma_deg * M_PI / 180.0;
  Vector6d vision_variance;
  vision_variance << Eigen::Vector3d::Constant(sigma_rad * sigma_rad),
      Eigen::Vector3d::Constant(config_.wheel_vision_sigma_m * config_.wheel_vision_sigma_m);
  const Matrix6d vision_covariance = vision_variance.asDiagonal();
  check.frame_distance_sq = mahalanobis_sq(residual, prior.covariance + vision_covariance);
  describe_in_base_frame(registered, prior.T_previous_current, check);

  // Over the window the residuals add up to (to first order) the registered motion over the
  // window against the wheels' over it; both noises add up frame by frame. (Registrations
  // against one key-frame would telescope, but on the simulated corridor loop new key-frames
  // come every few frames and the summed residuals grew faster than one frame's error.)
  WheelResidual& slot = wheel_window_[wheel_window_next_];
  slot.residual = residual;
  slot.covariance = prior.covariance + vision_covariance;
  wheel_window_next_ = (wheel_window_next_ + 1) % wheel_window_.size();
  wheel_window_size_ = std::min(wheel_window_size_ + 1, wheel_window_.size());
  Vector6d window_residual = Vector6d::Zero();
  Matrix6d window_covariance = Matrix6d::Zero();
  for (std::size_t i = 0; i < wheel_window_size_; ++i) {
    window_residual += wheel_window_[i].residual;
    window_covariance += wheel_window_[i].covariance;
  }
  // Until the window is full its sum says no more than the frame alone.
  check.window_distance_sq =
      wheel_window_size_ == wheel_window_.size() ? mahalanobis_sq(window_residual, window_covariance) : 0.0;
  check.disagree = check.frame_distance_sq > config_.wheel_gate_chi2 || check.window_distance_sq > config_.wheel_gate_chi2;

  // A planar base can make the residual: nothing across the drive direction, in height or in
  // tilt beyond the vision noise. Along it the corridor's registrations err by up to 8 cm, so
  // the forward residual says too little to be tested.
  const bool planar = std::abs(check.lateral_residual_m) <= config_.wheel_vision_sigma_m &&
                      std::abs(check.height_residual_m) <= config_.wheel_vision_sigma_m &&
                      check.tilt_residual_deg <= config_.wheel_vision_sigma_deg;
  check.slip_shaped = planar && std::abs(check.yaw_residual_deg) >= config_.wheel_slip_yaw_deg;
  const bool strong = inliers >= config_.wheel_strong_inliers;

  if (vision_holds_) {
    // A disagreement vision won lasts for as long as vision keeps disagreeing in a way the base
    // can move. With vision holding the pose, a slip shows only its growth over one frame: it
    // lasts while that turns the same way at no less than the least rate that declares a slip
    // (wheel_slip_yaw_deg over wheel_slip_min_frames).
    const bool still_slipping =
        slip_sign_ * check.yaw_residual_deg >= least_slip_turn_deg();
    if ((check.disagree || check.slip_shaped || still_slipping) && planar) {
      check.vision_trusted = true;
      check.disagree_in_a_row = ++disagree_in_a_row_;
      return true;
    }
    vision_holds_ = false;
    // What the window holds was vision's to explain; the wheels are compared afresh.
    clear_wheel_window();
  }
  // The heading run excuses vision's height and tilt, not much across: registrations that turn
  // about the scene instead of the camera (photometric on the corridor loop: 1-2 deg with 5-9 cm
  // across, for a second) are no slip.
  const int turn = check.yaw_residual_deg > 0.0 ? 1 : -1;
  if (std::abs(check.yaw_residual_deg) < config_.wheel_slip_yaw_deg ||
      std::abs(check.lateral_residual_m) > 2.0 * config_.wheel_vision_sigma_m) {
    turning_in_a_row_ = 0;
  } else {
    turning_in_a_row_ = turn == turning_sign_ ? turning_in_a_row_ + 1 : 1;
    turning_sign_ = turn;
  }
  slip_shaped_in_a_row_ = check.slip_shaped ? slip_shaped_in_a_row_ + 1 : 0;
  // A base moved without its wheels moves away from where they put it frame after frame, so each
  // frame of the run disagrees by itself; a window that still holds an earlier error does not
  // count (simulated corridor loop, seed 4: vision sliding 7-8 cm along the corridor on every
  // other frame kept the window disagreeing for 15 frames).
  const bool frame_disagrees = check.frame_distance_sq > config_.wheel_gate_chi2;
  disagree_in_a_row_ = frame_disagrees && !check.slip_shaped && planar && strong ? disagree_in_a_row_ + 1 : 0;
  const bool slip = slip_shaped_in_a_row_ >= config_.wheel_slip_min_frames ||
                    turning_in_a_row_ >= config_.wheel_slip_heading_frames;
  if (slip || disagree_in_a_row_ >= config_.wheel_override_min_frames) {
    // One wheel slipped, or the base moved without its wheels: vision keeps the pose.
    check.vision_trusted = true;
    check.slip_event = true;
    check.disagree_in_a_row = slip ? std::max(slip_shaped_in_a_row_, turning_in_a_row_) : disagree_in_a_row_;
    ++wheel_slip_events_;
    vision_holds_ = true;
    slip_sign_ = slip ? turn : 0;
    disagree_in_a_row_ = check.disagree_in_a_row;
    slip_shaped_in_a_row_ = 0;
    turning_in_a_row_ = 0;
    return true;
  }
  if (!check.disagree) {
    // Both measure the same motion: combine them by their covariances (a Kalman update of the
    // prior by the registration), exp(K·r)·prior with K = Σ_wheels (Σ_wheels + Σ_vision)⁻¹.
    // Motion the wheels cannot see (across the floor plane) has no wheel variance and keeps the
    // prior's value; a planar base cannot make it.
    const Matrix6d gain = prior.covariance * (prior.covariance + vision_covariance).inverse();
    const Vector6d correction = gain * residual;
    Eigen::Isometry3d update = Eigen::Isometry3d::Identity();
    const double angle = correction.head<3>().norm();
    if (angle > 0.0) update.linear() = Eigen::AngleAxisd(angle, correction.head<3>() / angle).toRotationMatrix();
    update.translation() = correction.tail<3>();
    result.T_world_cam = T_world_previous * (update * prior.T_previous_current);
    check.fused = true;
    return true;
  }
  // A registration error until shown otherwise (simulated corridor loop: single disagreeing
  // registrations were off by 35 mm median, the wheels by 0.04 mm).
  check.wheels_trusted = true;
  check.disagree_in_a_row = std::max({slip_shaped_in_a_row_, turning_in_a_row_, disagree_in_a_row_});
  return false;
}

void SlamLoop::describe_in_base_frame(const Eigen::Isometry3d& registered, const Eigen::Isometry3d& wheels,
                                      WheelCheck& check) const {
  const Eigen::Isometry3d T_cam_base = T_base_cam_.inverse();
  const Eigen::Isometry3d vision_base = T_base_cam_ * registered * T_cam_base;
  const Eigen::Isometry3d wheels_base = T_base_cam_ * wheels * T_cam_base;
  const Eigen::Vector3d step = vision_base.translation() - wheels_base.translation();
  check.forward_residual_m = step.x();
  check.lateral_residual_m = step.y();
  check.height_residual_m = step.z();
  const Eigen::Matrix3d& rotation = vision_base.linear();
  const Eigen::Matrix3d& wheel_rotation = wheels_base.linear();
  const double yaw_rad = std::remainder(
      std::atan2(rotation(1, 0), rotation(0, 0)) - std::atan2(wheel_rotation(1, 0), wheel_rotation(0, 0)), 2.0 * M_PI);
  check.yaw_residual_deg = yaw_rad * 180.0 / M_PI;
  // The wheels' rotation is about the vertical alone: vision's tilt of the vertical is all residual.
  check.tilt_residual_deg = std::acos(std::clamp(rotation(2, 2), -1.0, 1.0)) * 180.0 / M_PI;
}

FrameResult SlamLoop::process(const hal::RgbdFrame& frame) { return process(frame, nullptr); }

FrameResult SlamLoop::process(const hal::RgbdFrame& frame, const MotionPrior* prior) {
  if (config_.mode == Mode::kGeometric) return process_geometric(frame, prior);
  FrameResult result;
  result.wheels.prior_given = prior != nullptr;
  chain_restarted_ = false;
  auto stage_start = Clock::now();
  const ImageSource source = choose_source(frame);
  const cv::Mat* image = feature_image(frame, source);
  const bool have_depth = valid_image(frame.depth, CV_16UC1, camera_.width(), camera_.height());
  result.image_source = source;
  result.times.ms[kPreprocess] = elapsed_ms(stage_start);

  stage_start = Clock::now();
  int current = 0;
  while (current == reference_ || current == previous_) ++current;
  TrackedFrame& tracked = frames_[static_cast<std::size_t>(current)];
  const bool fused = config_.mode == Mode::kFused;
  const auto extract_photometric = [&] {
    if (image != nullptr && have_depth) {
      (source == ImageSource::kInfrared ? infrared_orb_ : orb_).extract(*image, frame.depth, tracked.features);
    } else {
      tracked.features.clear();
    }
  };
  // Fused: the ORB features on the companion thread while the geometric ones take the team
  // (fr1_rpy_head features stage, README "Speed").
  if (fused) {
    companion_.launch(extract_photometric);
    if (!have_depth || geometric_.extract(frame.depth, tracked.geometric) != geometry::GeometryStatus::kOk) {
      tracked.geometric.count = 0;
    }
    companion_.wait();
  } else {
    extract_photometric();
  }
  tracked.features.source = source;
  tracked.id = ++frame_counter_;
  const double frame_dt_s =
      previous_ >= 0 ? std::clamp(frame.stamp_s - previous_stamp_s_, 0.005, 0.5) : 1.0 / 30.0;
  previous_stamp_s_ = frame.stamp_s;
  tracked.velocity = velocity_of(predicted_motion(prior), frame_dt_s);
  result.features = static_cast<int>(tracked.features.size()) + (fused ? tracked.geometric.count : 0);
  result.times.ms[kFeatures] = elapsed_ms(stage_start);
  if (config_.icp_mode != IcpMode::kOff) {
    stage_start = Clock::now();
    if (have_depth) {
      icp_.build_cloud(frame.depth, tracked.cloud);
    } else {
      tracked.cloud.points.clear();
      tracked.cloud.normals.clear();
    }
    result.times.ms[kIcp] = elapsed_ms(stage_start);
  }

  current_photometric_ = &tracked.features;
  current_velocity_ = tracked.velocity;
  current_geometric_ = fused ? &tracked.geometric : nullptr;
  bool new_reference = false;
  if (previous_ < 0) {
    result.status = FrameStatus::kFirstFrame;
    result.T_world_cam = Eigen::Isometry3d::Identity();
    new_reference = true;
    current_covariance_.setZero();
    step_covariance_.setZero();
    finish_frame(frame, have_depth, Eigen::Isometry3d::Identity(), nullptr, result);
  } else {
    const TrackedFrame& previous = frames_[static_cast<std::size_t>(previous_)];
    const TrackedFrame& reference = frames_[static_cast<std::size_t>(reference_)];
    const Eigen::Isometry3d& predicted_step = predicted_motion(prior);
    const Eigen::Isometry3d T_world_predicted = previous.T_world_cam * predicted_step;
    std::string_view reason;
    accepted_information_.setZero();
    // Fused mode registers on depth alone when the frame has no usable image.
    if (image == nullptr && !fused) reason = "no usable image";
    if (!have_depth) reason = "no usable depth";
    const TrackedFrame* target = nullptr;
    // After a failed frame the prediction extrapolates the last motion, which may be the wrong
    // estimate that started the failure (fr1_rpy_head: one bad step of 11 cm, then 16 frames of
    // strong registrations against the reference rejected as far from the extrapolation, and the
    // track resumed 0.6 m off from the extrapolated previous frame). The reference's pose was
    // measured: a registration that sees it as well as tracked frames do sets the pose again.
    const bool resuming = failed_in_a_row_ > 0 && prior == nullptr;
    resumed_tracking_ = false;
    bool poor_fit = false;
    if (reason.empty()) {
      if (reference.features.source == source) {
        const MotionEstimate estimate = register_frames(
            reference.features, reference.velocity, tracked.features, tracked.velocity, result,
            reference.T_world_cam.inverse() * T_world_predicted, reference.T_world_cam.inverse() * previous.T_world_cam,
            fused ? &reference.geometric : nullptr, fused ? &tracked.geometric : nullptr);
        if (accept(estimate, reference.T_world_cam, previous.T_world_cam, predicted_step, result.T_world_cam, reason,
                   resuming)) {
          target = &reference;
          accepted_information_ = estimate.information;
          resumed_tracking_ = resuming;
          // Overlap relative to the inliers the reference had with the first frame registered
          // against it: that count is what full overlap looks like for this scene and image kind.
          // A fraction of the reference's features would depend on how matchable the features
          // are: fr1 colour frames match 55-60 % of them, IR frames 25-35 %, simulated colour
          // frames 95 %. (Measured with 0.6 of the features: IR references never lasted and the
          // dark office drifted to 0.13 m ATE; relative 0.5: 0.020 m.)
          if (reference_inliers_ == 0) reference_inliers_ = std::max(1, estimate.inliers);
          new_reference = estimate.inliers < config_.reference_min_overlap * reference_inliers_;
          poor_fit = !resuming && estimate.noise_scale > config_.reference_max_noise_scale;
        }
      } else if (const cv::Mat* bridge_image = feature_image(frame, reference.features.source);
                 bridge_image != nullptr) {
        stage_start = Clock::now();
        (reference.features.source == ImageSource::kInfrared ? infrared_orb_ : orb_)
            .extract(*bridge_image, frame.depth, bridge_);
        result.times.ms[kFeatures] += elapsed_ms(stage_start);
        const MotionEstimate estimate = register_frames(
            reference.features, reference.velocity, bridge_, tracked.velocity, result,
            reference.T_world_cam.inverse() * T_world_predicted, reference.T_world_cam.inverse() * previous.T_world_cam,
            fused ? &reference.geometric : nullptr, fused ? &tracked.geometric : nullptr);
        if (accept(estimate, reference.T_world_cam, previous.T_world_cam, predicted_step, result.T_world_cam, reason)) {
          target = &reference;
          accepted_information_ = estimate.information;
        }
        new_reference = true;  // the following frames need a reference of the new kind
      }
      // Measured alternative: registering against the previous frame as well whenever the
      // overlap is low, keeping the result with more inliers, cost one more registration and
      // raised the ATE (fr1_rpy_head seeds 1-6 mean 0.028 -> 0.034 m, dark office 0.020 ->
      // 0.036 m): the previous frame is the fallback only.
      // A reference registration whose inliers fit far worse than their noise says has lost the
      // reference although its inlier count has not dropped yet: the previous frame, closer in
      // view, is registered too and the better fit kept (and the frame becomes the reference).
      // fr1_rpy_head fused, seed 4: a reference was held for 16 frames while its registrations'
      // noise scale rose from 0.6 to 7.3, the last ones 2 deg and 6 cm off. This runs on 1-5 of
      // the 180 frames; fused ATE over seeds 1-5 with loop closure, bound 2.0: mean 0.0221 ->
      // 0.0200 m (1.5: 0.0192, 3.0: 0.0201), without 0.0279 -> 0.0267 m.
      if ((target == nullptr || poor_fit) && previous_ != reference_ && previous.features.source == source) {
        const FrameResult from_reference = result;
        const MotionEstimate estimate =
            register_frames(previous.features, previous.velocity, tracked.features, tracked.velocity, result,
                            predicted_step, Eigen::Isometry3d::Identity(), fused ? &previous.geometric : nullptr,
                            fused ? &tracked.geometric : nullptr);
        if ((target == nullptr || estimate.noise_scale < from_reference.noise_scale) &&
            accept(estimate, previous.T_world_cam, previous.T_world_cam, predicted_step, result.T_world_cam,
                   reason)) {
          target = &previous;
          accepted_information_ = estimate.information;
          new_reference = true;
        } else if (target != nullptr) {
          const StageTimes times = result.times;
          result = from_reference;
          result.times = times;
        }
      }
    }
    if (target != nullptr) {
      if (config_.icp_mode != IcpMode::kOff) refine_with_icp(*target, tracked, result);
      if (prior != nullptr && !check_against_wheels(*prior, previous.T_world_cam, result.inliers, result)) {
        target = nullptr;
        reason = "registration disagrees with the wheels";
      }
    }
    if (new_reference && target == &reference && result.wheels.fused &&
        std::abs(result.wheels.yaw_residual_deg) >= least_slip_turn_deg()) {
      // The pose took the wheels' heading, not vision's: as the next frames' reference it would
      // hide a slip building up. The old reference still registers, so it stays.
      new_reference = false;
    }
    if (target != nullptr) {
      result.status = FrameStatus::kTracking;
    } else {
      result.status = prior != nullptr ? FrameStatus::kWheels : FrameStatus::kFailed;
      result.failure_reason = reason;
      new_reference = false;  // the reference stays: the next frame that sees it snaps back
    }
    chain_covariance(target, target == &reference ? reference_covariance_ : previous_covariance_, result);
    finish_frame(frame, have_depth, previous.T_world_cam, prior, result);
  }
  tracked.T_world_cam = result.T_world_cam;
  if (chain_restarted_ && !new_reference && previous_ >= 0) {
    // The reference is older than the key-frame this frame became: its pose relative to the
    // key-frame is the inverse of this frame's registration, T_K_r = (T_r_K·exp(b))⁻¹ =
    // T_K_r·exp(−Ad(T_r_K)·b).
    const Matrix6d carry =
        adjoint(frames_[static_cast<std::size_t>(reference_)].T_world_cam.inverse() * result.T_world_cam);
    reference_covariance_ = carry * step_covariance_ * carry.transpose();
  }
  previous_covariance_ = current_covariance_;
  if (new_reference) {
    reference_ = current;
    reference_inliers_ = 0;
    reference_covariance_ = current_covariance_;
  }
  previous_ = current;
  result.new_reference = new_reference;
  return result;
}

void SlamLoop::finish_frame(const hal::RgbdFrame& frame, bool have_depth, const Eigen::Isometry3d& T_world_previous,
                            const MotionPrior* prior, FrameResult& result) {
  accumulate_wheel_motion(prior);
  if (!result.wheels.compared) {
    // The window and the runs count consecutive compared frames only.
    clear_wheel_window();
    disagree_in_a_row_ = 0;
    slip_shaped_in_a_row_ = 0;
    turning_in_a_row_ = 0;
    vision_holds_ = false;
  }
  if (result.status == FrameStatus::kTracking) {
    result.T_world_cam = rigid(result.T_world_cam);
    // A frame that resumed tracking jumped from an extrapolated pose: that is no motion to go on
    // with, so the next prediction holds the pose.
    last_motion_ = resumed_tracking_ ? Eigen::Isometry3d::Identity() : rigid(T_world_previous.inverse() * result.T_world_cam);
    T_world_last_tracked_ = result.T_world_cam;
    failed_in_a_row_ = 0;
  } else if (result.status == FrameStatus::kWheels && prior != nullptr) {
    // The wheels carry the pose; their motion is also the best constant-velocity model should
    // the next frame come without a prior.
    last_motion_ = prior->T_previous_current;
    result.T_world_cam = rigid(T_world_previous * last_motion_);
    T_world_last_tracked_ = result.T_world_cam;
    failed_in_a_row_ = 0;
  } else if (result.status == FrameStatus::kFailed) {
    // Constant-velocity extrapolation keeps the pose continuous through a short gap; a long gap
    // holds the pose instead (see max_extrapolated_frames).
    if (++failed_in_a_row_ > config_.max_extrapolated_frames) last_motion_ = Eigen::Isometry3d::Identity();
    result.T_world_cam = rigid(T_world_previous * last_motion_);
  }

  const auto stage_start = Clock::now();
  const Eigen::Isometry3d since_keyframe = T_world_last_keyframe_.inverse() * result.T_world_cam;
  if (result.status == FrameStatus::kFirstFrame ||
      (result.status == FrameStatus::kTracking &&
       (since_keyframe.translation().norm() > config_.keyframe_translation_m ||
        rotation_deg(since_keyframe) > config_.keyframe_rotation_deg))) {
    T_world_last_keyframe_ = result.T_world_cam;
    result.keyframe = true;
    ++keyframes_;
    store_keyframe(frame, have_depth, result);
  }
  continue_loop_search(config_.loop_candidates_per_frame, result);
  if (latest_keyframe_slot_ >= 0) {
    const StoredKeyframe& keyframe = keyframe_store_.slot(latest_keyframe_slot_);
    result.keyframe_node = keyframe.node;
    result.keyframe_generation = keyframe.generation;
    result.T_keyframe_cam = keyframe.T_world_cam.inverse() * result.T_world_cam;
  }
  run_backend(result);
  result.times.ms[kMapping] = elapsed_ms(stage_start);
}

void SlamLoop::store_keyframe(const hal::RgbdFrame& frame, bool have_depth, FrameResult& result) {
  int slot = keyframe_store_.free_slot();
  if (slot < 0) {
    // Full: retire a key-frame away from here (the loop search would not pick it soon) with the
    // fewest loop closures; its graph edges are composed through a neighbour, so the graph
    // stays connected.
    slot = keyframe_store_.retirement_candidate(result.T_world_cam, 2.0 * config_.loop_search_radius_m,
                                                config_.loop_min_keyframe_gap);
    if (slot < 0) {
      if (have_depth) add_keyframe_to_map(frame, result.T_world_cam, nullptr);
      return;
    }
    graph_.remove_node(keyframe_store_.slot(slot).node);
    keyframe_store_.release(slot);
    ++retired_keyframes_;
  }
  keyframe_store_.occupy(slot);
  StoredKeyframe& keyframe = keyframe_store_.slot(slot);
  keyframe.sequence = ++keyframe_sequence_;
  keyframe.stamp_s = frame.stamp_s;
  keyframe.T_world_cam = result.T_world_cam;
  keyframe.velocity = current_velocity_;
  if (current_photometric_ != nullptr) {
    KeyframeStore::copy_features(*current_photometric_, keyframe.photometric);
  } else {
    keyframe.photometric.clear();
  }
  if (current_geometric_ != nullptr && keyframe.geometric.capacity() > 0) {
    KeyframeStore::copy_features(*current_geometric_, keyframe.geometric);
  } else {
    keyframe.geometric.count = 0;
  }
  keyframe.node = graph_.add_node(keyframe.T_world_cam);
  keyframe.generation = keyframe.node >= 0 ? graph_.generation(keyframe.node) : 0;
  if (latest_keyframe_slot_ >= 0 && latest_keyframe_slot_ != slot) {
    const StoredKeyframe& previous = keyframe_store_.slot(latest_keyframe_slot_);
    const Eigen::Isometry3d T_previous_current = previous.T_world_cam.inverse() * keyframe.T_world_cam;
    path_m_ += T_previous_current.translation().norm();
    if (previous.used && previous.node >= 0 && keyframe.node >= 0) {
      graph::Edge edge;
      edge.from = previous.node;
      edge.to = keyframe.node;
      edge.T_from_to = T_previous_current;
      if (config_.mode != Mode::kGeometric) {
        // As uncertain as the chain of registrations from the previous key-frame: a direction
        // one weak registration on the way left to the motion model (along a plain corridor) is
        // weak in the edge, so a loop closure's correction goes there (corridor loop, seed 1, no
        // wheels: ATE with loop closure 0.0589 m with the key-frame's own registration's
        // information, 0.0582 m with the chain's).
        edge.information = symmetric_inverse(current_covariance_);
      } else {
        edge.information = registration_information(std::max(result.inliers, config_.min_inliers), result.noise_scale);
      }
      edge.kind = graph::EdgeKind::kSequential;
      (void)graph_.add_edge(edge);
      add_planar_edge(previous.node, keyframe.node, T_previous_current);
      add_wheel_edge(previous.node, keyframe.node);
    }
  }
  wheel_since_keyframe_ = Eigen::Isometry3d::Identity();
  wheel_since_keyframe_covariance_.setZero();
  wheel_since_keyframe_valid_ = true;
  current_covariance_.setZero();
  chain_restarted_ = true;
  keyframe.path_m = path_m_;
  if (have_depth) add_keyframe_to_map(frame, result.T_world_cam, &keyframe);
  latest_keyframe_slot_ = slot;
  // A search still under way for the previous key-frame ends before this one's starts.
  continue_loop_search(0, result);
  if (result.status == FrameStatus::kTracking && keyframe.node >= 0) start_loop_search(slot);
}

void SlamLoop::accumulate_wheel_motion(const MotionPrior* prior) {
  if (prior == nullptr) {
    wheel_since_keyframe_valid_ = false;
    return;
  }
  // Both covariances are of a small motion applied on the left in the earlier frame:
  // exp(ξ_a)·A · exp(ξ_b)·B = exp(ξ_a + Ad(A)·ξ_b)·A·B to first order.
  const Matrix6d to_keyframe = adjoint(wheel_since_keyframe_);
  wheel_since_keyframe_covariance_ += to_keyframe * prior->covariance * to_keyframe.transpose();
  wheel_since_keyframe_ = rigid(wheel_since_keyframe_ * prior->T_previous_current);
}

void SlamLoop::add_planar_edge(int from_node, int to_node, const Eigen::Isometry3d& T_from_to) {
  if (!differential_drive_ || config_.graph_planar_sigma_m <= 0.0 || config_.graph_planar_sigma_deg <= 0.0) return;
  // A differential-drive base stays on the floor: between two key-frames its height, roll and
  // pitch do not change. The graph composes edges through covariances when it retires a node,
  // hence the floor on the free three (see planar_constraint).
  const PlanarConstraint constraint = planar_constraint(T_from_to, T_base_cam_, config_.graph_planar_sigma_m,
                                                        config_.graph_planar_sigma_deg * M_PI / 180.0);
  graph::Edge edge;
  edge.from = from_node;
  edge.to = to_node;
  edge.T_from_to = rigid(constraint.T_from_to);
  edge.information = constraint.information;
  edge.kind = graph::EdgeKind::kSequential;
  (void)graph_.add_edge(edge);
}

void SlamLoop::add_wheel_edge(int from_node, int to_node) {
  if (!wheel_since_keyframe_valid_ || config_.graph_wheel_floor_m <= 0.0) return;
  // The graph's error sits on the right, in the later key-frame: Σ_right = Ad(T⁻¹)·Σ_left·Ad(T⁻¹)ᵀ.
  // Motion a planar base cannot measure (roll, pitch, height) has no wheel variance; the floor
  // keeps the information finite there.
  const Matrix6d to_current = adjoint(wheel_since_keyframe_.inverse());
  Matrix6d covariance = to_current * wheel_since_keyframe_covariance_ * to_current.transpose();
  const double floor_rad = config_.graph_wheel_floor_deg * M_PI / 180.0;
  covariance.diagonal().head<3>().array() += floor_rad * floor_rad;
  covariance.diagonal().tail<3>().array() += config_.graph_wheel_floor_m * config_.graph_wheel_floor_m;
  graph::Edge edge;
  edge.from = from_node;
  edge.to = to_node;
  edge.T_from_to = wheel_since_keyframe_;
  edge.information = symmetric_inverse(covariance);
  edge.kind = graph::EdgeKind::kWheels;
  (void)graph_.add_edge(edge);
}

graph::Matrix6d SlamLoop::sequential_information_floor() const {
  // One match's rotation information and a hundredth of its translation information: what the
  // surfaces leave free must not make the graph singular.
  return graph::information_from_matches(1, config_.graph_match_sigma_deg * M_PI / 180.0,
                                         10.0 * config_.graph_match_sigma_m);
}

void SlamLoop::chain_covariance(const TrackedFrame* target, const Matrix6d& target_covariance,
                                const FrameResult& result) {
  if (target == nullptr) {
    // Not registered: the pose is extrapolated or the wheels'; a frame registered against it
    // later inherits no more than one floor's worth of confidence.
    step_covariance_ = symmetric_inverse(sequential_information_floor());
    current_covariance_ = target_covariance + step_covariance_;
    return;
  }
  const Matrix6d information =
      (accepted_information_.any()
           ? Matrix6d(accepted_information_)
           : registration_information(std::max(result.inliers, config_.min_inliers), result.noise_scale)) +
      sequential_information_floor();
  step_covariance_ = symmetric_inverse(information);
  // T_K_c·exp(ξ_c) = T_K_t·exp(ξ_t)·T_t_c·exp(ξ) gives ξ_c = Ad(T_t_c⁻¹)·ξ_t + ξ.
  const Matrix6d carry = adjoint((target->T_world_cam.inverse() * result.T_world_cam).inverse());
  current_covariance_ = carry * target_covariance * carry.transpose() + step_covariance_;
}

graph::Matrix6d SlamLoop::registration_information(int inliers, double noise_scale) const {
  // The thesis weights an edge by its inlier count, which presumes every registration fits its
  // matches as well as their predicted noise says. Where the inliers fit worse (noise scale s > 1:
  // a blurred key-frame, a rolling-shutter velocity that was off, an alignment pulled by a wrong
  // subset), the registration is that much less certain: the a-posteriori variance factor s²
  // divides the information. Below 1 the noise model is merely conservative and the count
  // stands. fr1_rpy_head against ground truth: sequential edges have s = 0.55-1.5; the accepted
  // loop closures that pulled the trajectory most were off by 3-4 deg and 8-13 cm with
  // s = 3.4-8.2, good ones have s = 0.6-1.2. Fused ATE over seeds 1-5: mean 0.0250 -> 0.0221 m
  // (photometric 0.0214 -> 0.0208 m).
  const double variance_factor = std::max(1.0, noise_scale * noise_scale);
  return graph::information_from_matches(inliers, config_.graph_match_sigma_deg * M_PI / 180.0,
                                         config_.graph_match_sigma_m) /
         variance_factor;
}

void SlamLoop::start_loop_search(int slot) {
  loop_candidates_.clear();
  loop_candidates_tried_ = loop_candidates_next_ = 0;
  loop_search_slot_ = -1;
  loop_search_geometric_ = nullptr;
  if (config_.loop_max_candidates == 0) return;
  const StoredKeyframe& current = keyframe_store_.slot(slot);
  for (int i = 0; i < keyframe_store_.capacity(); ++i) {
    const StoredKeyframe& stored = keyframe_store_.slot(i);
    if (!stored.used || i == slot || stored.node < 0) continue;
    if (stored.sequence > current.sequence - config_.loop_min_keyframe_gap) continue;
    if (current_geometric_ == nullptr && stored.photometric.source != current.photometric.source) continue;
    const double travelled_m = current.path_m - stored.path_m;
    const Eigen::Isometry3d relative = stored.T_world_cam.inverse() * current.T_world_cam;
    const double distance_m = relative.translation().norm();
    if (distance_m > config_.loop_search_radius_m + config_.loop_drift_per_m * travelled_m ||
        rotation_deg(relative) > config_.loop_search_rotation_deg + config_.loop_drift_deg_per_m * travelled_m) {
      continue;
    }
    loop_candidates_.push_back({distance_m, i, stored.sequence});
  }
  if (loop_candidates_.empty()) return;
  loop_candidates_tried_ = std::min(loop_candidates_.size(), static_cast<std::size_t>(config_.loop_max_candidates));
  const auto tried_end = loop_candidates_.begin() + static_cast<std::ptrdiff_t>(loop_candidates_tried_);
  std::partial_sort(loop_candidates_.begin(), tried_end, loop_candidates_.end());
  // The frame's own features serve a search that ends in this frame; one that carries over into
  // the next frames keeps a copy (the frame's buffer is reused).
  const int per_frame = config_.loop_candidates_per_frame;
  loop_search_geometric_ = current_geometric_;
  if (current_geometric_ != nullptr && per_frame > 0 && loop_candidates_tried_ > static_cast<std::size_t>(per_frame)) {
    if (!loop_search_copy_.assign_from(*current_geometric_)) return;  // set-up sizes both alike: not reached
    loop_search_geometric_ = &loop_search_copy_;
  }
  loop_search_slot_ = slot;
  loop_search_sequence_ = current.sequence;
}

void SlamLoop::continue_loop_search(int count, FrameResult& result) {
  if (loop_search_slot_ < 0) return;
  // Either key-frame may have been retired from the store since the search started.
  const StoredKeyframe& current = keyframe_store_.slot(loop_search_slot_);
  const bool current_kept = current.used && current.sequence == loop_search_sequence_ && current.node >= 0;
  for (int done = 0; current_kept && loop_candidates_next_ < loop_candidates_tried_ && (count == 0 || done < count);
       ++done) {
    const LoopCandidate& candidate = loop_candidates_[loop_candidates_next_++];
    StoredKeyframe& stored = keyframe_store_.slot(candidate.slot);
    if (!stored.used || stored.sequence != candidate.sequence || stored.node < 0) continue;
    try_loop_candidate(stored, result);
    ++result.loop_candidates;
  }
  if (!current_kept || loop_candidates_next_ >= loop_candidates_tried_) loop_search_slot_ = -1;
}

void SlamLoop::try_loop_candidate(StoredKeyframe& stored, FrameResult& result) {
  StoredKeyframe& current = keyframe_store_.slot(loop_search_slot_);
  const bool with_geometry = loop_search_geometric_ != nullptr;
  const Eigen::Isometry3d predicted = stored.T_world_cam.inverse() * current.T_world_cam;
  FrameResult scratch;
  const MotionEstimate estimate = register_frames(
      stored.photometric, stored.velocity, current.photometric, current.velocity, scratch, predicted, predicted,
      with_geometry ? &stored.geometric : nullptr, with_geometry ? &current.geometric : nullptr, /*refine=*/false);
  if (!estimate.ok || !estimate.T_target_source.matrix().allFinite()) return;
  const int photometric_inliers = with_geometry ? scratch.photometric_inliers : scratch.inliers;
  const int geometric_inliers = with_geometry ? scratch.geometric_inliers : 0;
  if (photometric_inliers + geometric_inliers < loop_threshold_.value()) return;
  // Where tracking needs the geometric ICP for its precision (photometric inliers few or poorly
  // spread), a closure on descriptor matches alone is less precise than the chain it would
  // correct (simulated zigzag-plain, fused ATE 0.027 m with such closures, 0.0007 m without;
  // on the corridor loop they were 2-9 cm and 0.5-1.7 deg off): it is refined as tracking is,
  // on the key-frame's stored cloud, the feature estimate holding what the view leaves free,
  // and is not taken unrefined.
  Eigen::Isometry3d T_stored_current = estimate.T_target_source;
  bool refined_by_icp = false;
  if (with_geometry && photometric_needs_refinement(config_.loop_icp_above_rotation_sigma_deg)) {
    if (stored.geometric.cloud_count < 3 || loop_search_geometric_->cloud_count < 3) return;
    geometry::IcpPrior feature_prior;
    feature_prior.T_previous_current = estimate.T_target_source;
    feature_prior.information =
        step_prior_information(estimate.T_target_source, Eigen::Isometry3d::Identity(), icp_prior_information_);
    const geometry::FrameRegistration refined =
        geometric_.register_frames(stored.geometric, *loop_search_geometric_, estimate.T_target_source, feature_prior);
    if (!refined.ok || refined.refined_from == geometry::RefinementStart::kNone ||
        refined.icp_inliers < config_.min_icp_inliers) {
      return;
    }
    // Refinement that could not fix what the features left loose keeps their error.
    if (least_information_ratio(refined.icp_information, feature_prior.information) <
        config_.loop_icp_min_information_ratio) {
      return;
    }
    T_stored_current = refined.T_previous_current;
    refined_by_icp = true;
  }

  // Pose consistency: a true closure corrects the drift accumulated since the candidate, no more.
  const double travelled_m = current.path_m - stored.path_m;
  const Eigen::Isometry3d correction = predicted.inverse() * T_stored_current;
  if (correction.translation().norm() > config_.loop_max_correction_m + config_.loop_drift_per_m * travelled_m ||
      rotation_deg(correction) > config_.loop_max_correction_deg + config_.loop_drift_deg_per_m * travelled_m) {
    return;
  }
  // Inlier geometry: the matches that fit must spread in two directions at least; matches on a
  // line or in one small patch fit a wrong motion as well as the right one.
  const Eigen::Isometry3f T = estimate.T_target_source.cast<float>();
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_sq = Eigen::Matrix3d::Zero();
  int inliers = 0;
  for (std::size_t i = 0; i < source_points_.size(); ++i) {
    const double residual = (T * source_points_[i] - target_points_[i]).norm();
    if (residual > 3.0 * correspondence_sigma_m_[i]) continue;
    const Eigen::Vector3d p = source_points_[i].cast<double>();
    sum += p;
    sum_sq += p * p.transpose();
    ++inliers;
  }
  if (inliers < config_.min_inliers) return;
  const Eigen::Vector3d mean = sum / inliers;
  const Eigen::Matrix3d covariance = sum_sq / inliers - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> spread(covariance, Eigen::EigenvaluesOnly);
  if (std::sqrt(std::max(0.0, spread.eigenvalues()(1))) < config_.loop_min_inlier_spread_m) return;

  graph::Edge edge;
  edge.from = stored.node;
  edge.to = current.node;
  edge.T_from_to = rigid(T_stored_current);
  if (refined_by_icp) {
    // As a sequential ICP-refined edge: what the surfaces fix, plus the feature inliers where
    // they fit their noise. A closure the view leaves free in a direction (a robot that turned
    // back to face the same plain corridor) then does not pull the chain along it.
    edge.information = cloud_surface_information(*loop_search_geometric_, config_.graph_icp_sigma_m);
    if (estimate.noise_scale <= config_.fused_max_noise_scale) {
      edge.information += correspondence_information(estimate.T_target_source, source_points_, target_points_,
                                                     correspondence_sigma_m_) /
                          std::max(1.0, estimate.noise_scale * estimate.noise_scale);
    }
  } else {
    edge.information = registration_information(photometric_inliers + geometric_inliers, estimate.noise_scale);
  }
  edge.kind = graph::EdgeKind::kLoopClosure;
  if (!graph_.add_edge(edge)) return;
  ++stored.loop_closures;
  ++current.loop_closures;
  LoopClosure& logged = closure_log_[static_cast<std::size_t>(loop_closures_) % closure_log_.size()];
  logged.stored_stamp_s = stored.stamp_s;
  logged.current_stamp_s = current.stamp_s;
  logged.T_stored_current = edge.T_from_to;
  logged.photometric_inliers = photometric_inliers;
  logged.geometric_inliers = geometric_inliers;
  logged.threshold = loop_threshold_.value();
  loop_threshold_.add(photometric_inliers, geometric_inliers);
  ++loop_closures_;
  result.loop_closure = true;
  graph_pending_ = true;
}

const LoopClosure* SlamLoop::loop_closure(int index) const {
  const int capacity = static_cast<int>(closure_log_.size());
  if (index < 0 || index >= loop_closures_ || index < loop_closures_ - capacity) return nullptr;
  return &closure_log_[static_cast<std::size_t>(index % capacity)];
}

void SlamLoop::run_backend(FrameResult& result) {
  if (graph_pending_ && !optimizer_.busy() && optimizer_.submit(graph_, config_.graph_iterations)) {
    graph_pending_ = false;
    if (synchronous_backend_) (void)optimizer_.wait_until_idle(std::chrono::minutes(5));
  }
  if (optimizer_.take_result(optimized_)) apply_optimized_graph(result);
}

void SlamLoop::apply_optimized_graph(FrameResult& result) {
  if (!optimized_.summary().ok) return;
  // The newest key-frame the solve included carries the tracking: its correction moves the
  // key-frames added since and every pose the tracking holds.
  Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();
  std::int64_t newest = -1;
  for (int i = 0; i < keyframe_store_.capacity(); ++i) {
    StoredKeyframe& keyframe = keyframe_store_.slot(i);
    if (!keyframe.used || keyframe.node < 0 || !optimized_.contains(keyframe.node) ||
        optimized_.generation(keyframe.node) != keyframe.generation) {
      continue;
    }
    const Eigen::Isometry3d& optimized = optimized_.pose(keyframe.node);
    if (keyframe.sequence > newest) {
      newest = keyframe.sequence;
      correction = rigid(optimized * keyframe.T_world_cam.inverse());
    }
    keyframe.T_world_cam = optimized;
    (void)graph_.set_pose(keyframe.node, optimized);
  }
  if (newest < 0) return;
  for (int i = 0; i < keyframe_store_.capacity(); ++i) {
    StoredKeyframe& keyframe = keyframe_store_.slot(i);
    if (!keyframe.used || keyframe.node < 0) continue;
    if (optimized_.contains(keyframe.node) && optimized_.generation(keyframe.node) == keyframe.generation) continue;
    keyframe.T_world_cam = rigid(correction * keyframe.T_world_cam);
    (void)graph_.set_pose(keyframe.node, keyframe.T_world_cam);
  }
  correct_tracking(correction);
  result.T_world_cam = rigid(correction * result.T_world_cam);
  result.graph_applied = true;
  result.map_correction = rigid(correction * result.map_correction);
}

void SlamLoop::correct_tracking(const Eigen::Isometry3d& correction) {
  for (TrackedFrame& tracked : frames_) tracked.T_world_cam = rigid(correction * tracked.T_world_cam);
  T_world_last_keyframe_ = rigid(correction * T_world_last_keyframe_);
  T_world_geometric_previous_ = rigid(correction * T_world_geometric_previous_);
  T_world_geometric_target_ = rigid(correction * T_world_geometric_target_);
}

void SlamLoop::finish() {
  {
    FrameResult ignored;
    continue_loop_search(0, ignored);
  }
  if (graph_pending_) {
    (void)optimizer_.wait_until_idle(std::chrono::minutes(5));
    FrameResult ignored;
    if (optimizer_.take_result(optimized_)) apply_optimized_graph(ignored);
    if (optimizer_.submit(graph_, config_.graph_iterations)) graph_pending_ = false;
  }
  (void)optimizer_.wait_until_idle(std::chrono::minutes(5));
  FrameResult ignored;
  if (optimizer_.take_result(optimized_)) apply_optimized_graph(ignored);
  if (loop_closures_ == 0) return;  // the live map already sits on the only poses there are
  map_.clear();
  for (int i = 0; i < keyframe_store_.capacity(); ++i) {
    const StoredKeyframe& keyframe = keyframe_store_.slot(i);
    if (!keyframe.used) continue;
    const Eigen::Isometry3f T = keyframe.T_world_cam.cast<float>();
    for (int p = 0; p < keyframe.point_count; ++p) {
      const KeyframePoint& point = keyframe.points[static_cast<std::size_t>(p)];
      map_.insert(T * point.point_cam, point.blue, point.green, point.red);
    }
  }
}

bool SlamLoop::optimized_pose(int keyframe_node, std::uint32_t keyframe_generation,
                              const Eigen::Isometry3d& T_keyframe_cam, Eigen::Isometry3d& T_world_cam) const {
  if (keyframe_node < 0 || !graph_.contains(keyframe_node) || graph_.generation(keyframe_node) != keyframe_generation) {
    return false;
  }
  T_world_cam = rigid(graph_.pose(keyframe_node) * T_keyframe_cam);
  return true;
}

FrameResult SlamLoop::process_geometric(const hal::RgbdFrame& frame, const MotionPrior* prior) {
  FrameResult result;
  result.wheels.prior_given = prior != nullptr;
  auto stage_start = Clock::now();
  const bool have_depth = valid_image(frame.depth, CV_16UC1, camera_.width(), camera_.height());
  gray_valid_ = valid_image(frame.rgb, CV_8UC3, camera_.width(), camera_.height());  // map colour only
  infrared_valid_ = false;
  result.times.ms[kPreprocess] = elapsed_ms(stage_start);

  stage_start = Clock::now();
  const int current = geometric_previous_ == 0 ? 1 : 0;
  geometry::GeometricFeatures& features = geometric_features_[static_cast<std::size_t>(current)];
  const geometry::GeometryStatus extracted =
      have_depth ? geometric_.extract(frame.depth, features) : geometry::GeometryStatus::kInvalidImage;
  if (extracted != geometry::GeometryStatus::kOk) features.count = 0;
  result.features = features.count;
  current_photometric_ = nullptr;
  current_geometric_ = &features;
  current_velocity_ = Velocity::Zero();
  result.times.ms[kFeatures] = elapsed_ms(stage_start);

  if (geometric_previous_ < 0) {
    result.status = FrameStatus::kFirstFrame;
    result.T_world_cam = Eigen::Isometry3d::Identity();
    finish_frame(frame, have_depth, Eigen::Isometry3d::Identity(), nullptr, result);
  } else {
    std::string_view reason;
    if (!have_depth) reason = "no usable depth";
    else if (extracted != geometry::GeometryStatus::kOk) reason = geometry::to_string(extracted);
    bool tracked = false;
    int descriptor_inliers = 0;
    if (reason.empty()) {
      // The target is the last frame with features, which is older than the previous frame when
      // frames without features came in between.
      const Eigen::Isometry3d guess =
          T_world_geometric_target_.inverse() * T_world_geometric_previous_ * predicted_motion(prior);
      const geometry::FrameRegistration registration = geometric_.register_frames(
          geometric_features_[static_cast<std::size_t>(geometric_previous_)], features, guess);
      const geometry::StageTimes& times = geometric_.last_times();
      result.times.ms[kMatching] = times.matching_ms;
      result.times.ms[kEstimation] = times.msse_ms;
      result.times.ms[kIcp] = times.icp_ms;
      result.matches = registration.matches;
      // With the ICP stage the final inliers are its point-to-plane inliers; without it, MSSE's.
      result.inliers = registration.refined_from != geometry::RefinementStart::kNone ? registration.icp_inliers
                                                                                     : registration.inliers;
      // How strongly the scene fixes the motion: the descriptor matches' MSSE inliers. ICP's
      // point inliers count in the thousands even where it slides along a plane.
      descriptor_inliers = registration.msse_ok ? registration.inliers : 0;
      MotionEstimate estimate;
      estimate.ok = registration.ok;
      estimate.T_target_source = registration.T_previous_current;
      estimate.inliers = result.inliers;
      estimate.failure_reason = geometry::to_string(registration.status);
      tracked = accept(estimate, T_world_geometric_target_, T_world_geometric_previous_, predicted_motion(prior),
                       result.T_world_cam, reason);
      if (tracked && prior != nullptr &&
          !check_against_wheels(*prior, T_world_geometric_previous_, descriptor_inliers, result)) {
        tracked = false;
        reason = "registration disagrees with the wheels";
      }
    }
    result.status = tracked ? FrameStatus::kTracking : (prior != nullptr ? FrameStatus::kWheels : FrameStatus::kFailed);
    if (!tracked) result.failure_reason = reason;
    finish_frame(frame, have_depth, T_world_geometric_previous_, prior, result);
  }
  // A frame without features cannot be the next frame's target; the last good one stays.
  if (features.count > 0 || geometric_previous_ < 0) {
    geometric_previous_ = current;
    T_world_geometric_target_ = result.T_world_cam;
  }
  T_world_geometric_previous_ = result.T_world_cam;
  return result;
}

void SlamLoop::add_keyframe_to_map(const hal::RgbdFrame& frame, const Eigen::Isometry3d& T_world_cam,
                                   StoredKeyframe* stored) {
  const Eigen::Isometry3f T = T_world_cam.cast<float>();
  std::uniform_int_distribution<int> column(0, camera_.width() - 1);
  std::uniform_int_distribution<int> row(0, camera_.height() - 1);
  const auto max_depth_m = static_cast<float>(config_.max_depth_m);
  // Colour from the colour image; grey from the IR image when there is no colour image.
  const cv::Mat* grey = gray_valid_ ? nullptr : feature_image(frame, ImageSource::kInfrared);
  if (!gray_valid_ && grey == nullptr) return;
  // Random pixels, as the thesis samples its map; attempts are capped so a frame with little
  // depth cannot stall the loop.
  int added = 0;
  for (int attempt = 0; attempt < config_.map_points_per_keyframe * 4 && added < config_.map_points_per_keyframe;
       ++attempt) {
    const int u = column(map_sampler_);
    const int v = row(map_sampler_);
    const unsigned short raw = frame.depth.at<unsigned short>(v, u);
    if (raw == 0) continue;
    const float z_m = camera_.metres(raw);
    if (z_m > max_depth_m) continue;
    const Eigen::Vector3f point_cam = camera_.back_project(u, v, z_m);
    const Eigen::Vector3f point = T * point_cam;
    KeyframePoint coloured{point_cam, 0, 0, 0};
    if (gray_valid_) {
      const cv::Vec3b bgr = frame.rgb.at<cv::Vec3b>(v, u);
      coloured.blue = bgr[0];
      coloured.green = bgr[1];
      coloured.red = bgr[2];
    } else {
      const unsigned char level = grey->at<unsigned char>(v, u);
      coloured.blue = coloured.green = coloured.red = level;
    }
    map_.insert(point, coloured.blue, coloured.green, coloured.red);
    if (stored != nullptr && stored->point_count < static_cast<int>(stored->points.size())) {
      stored->points[static_cast<std::size_t>(stored->point_count++)] = coloured;
    }
    ++added;
  }
}

}  // namespace rankslam::slam
