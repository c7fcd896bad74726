#include "feature_tracker.hpp"

#include "rankslam/core/lie.hpp"
#include "rankslam/core/stopwatch.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rankslam::slam {
namespace {

using enum StageTimes::Stage;

Registrar::Velocity velocity_of(const Eigen::Isometry3d& motion, double dt_s) {
  const Eigen::AngleAxisd rotation(motion.rotation());
  Registrar::Velocity velocity;
  velocity.head<3>() = rotation.angle() * rotation.axis() / dt_s;
  velocity.tail<3>() = motion.translation() / dt_s;
  return velocity;
}

}  // namespace

FeatureTracker::FeatureTracker(const TrackerParts& parts, bool fused)
    : parts_(parts),
      config_(parts.config),
      fused_(fused),
      orb_(config_, parts.camera),
      motion_(config_) {
  const auto capacity = static_cast<std::size_t>(config_.orb_features) * 2;
  for (auto& tracked : frames_) tracked.features.reserve(capacity);
  if (config_.dense_refinement != 0) {
    dense_.emplace(parts.camera, config_.dense_options(parts.camera.depth_noise_per_m()));
    for (auto& tracked : frames_) dense_->reserve(tracked.dense);
  }
  bridge_.reserve(capacity);
  if (!fused_) return;
  if (const std::string error = parts_.geometric.configure(parts.camera, config_.geometric_frontend(),
                                                           geometric_capacities(config_), &parts_.team);
      !error.empty()) {
    throw std::invalid_argument(error);
  }
  for (auto& tracked : frames_) tracked.geometric = parts_.geometric.make_features();
  parts_.registrar.size_geometric_matches();
  if (config_.threads > 1) {
    // The ORB features are extracted on the companion while the geometric ones take the team.
    if (const std::string error = parts_.companion.start(); !error.empty()) {
      throw std::invalid_argument("slam.threads: " + error);
    }
    const auto warm_up = [images = &parts_.images] { images->warm_up(); };
    parts_.companion.launch(warm_up);  // a thread of its own for OpenCV too
    parts_.companion.wait();
  }
}

void FeatureTracker::extract(const hal::RgbdFrame& frame, const cv::Mat* image, ImageSource source,
                             bool have_depth, const nav::MotionPrior* prior, FrameResult& result) {
  const auto stage_start = SteadyClock::now();
  TrackedFrame& tracked = frames_[static_cast<std::size_t>(current_)];
  const auto extract_photometric = [&] {
    if (image != nullptr && have_depth) {
      orb_.extract(*image, frame.depth, tracked.features, source);
    } else {
      tracked.features.clear();
    }
    // The dense refinement's pyramids beside the ORB features (on the companion in fused mode).
    if (dense_ && (image == nullptr || !have_depth ||
                   !tracked.dense.prepare(*image, frame.depth, parts_.camera.metres(1),
                                          static_cast<float>(config_.min_depth_m),
                                          static_cast<float>(config_.max_depth_m), static_cast<int>(source)))) {
      tracked.dense.invalidate();
    }
  };
  // Fused: the ORB features on the companion thread while the geometric ones take the team
  // (fr1_rpy_head features stage, docs/results.md §2.3).
  if (fused_) {
    parts_.companion.launch(extract_photometric);
    if (!have_depth || parts_.geometric.extract(frame.depth, tracked.geometric) != geometry::GeometryStatus::kOk) {
      tracked.geometric.count = 0;
    }
    parts_.companion.wait();
  } else {
    extract_photometric();
  }
  tracked.features.source = source;
  const double frame_dt_s =
      previous_ >= 0 ? std::clamp(frame.stamp_s - previous_stamp_s_, 0.005, 0.5) : 1.0 / 30.0;
  previous_stamp_s_ = frame.stamp_s;
  tracked.velocity = velocity_of(motion_.predicted(prior), frame_dt_s);
  result.features = static_cast<int>(tracked.features.size()) + (fused_ ? tracked.geometric.count : 0);
  result.times.ms[kFeatures] = elapsed_ms(stage_start);
}

void FeatureTracker::track(const hal::RgbdFrame& frame, const nav::MotionPrior* prior, FrameResult& result) {
  chain_restarted_ = false;
  const auto stage_start = SteadyClock::now();
  const ImageSource source = parts_.images.choose_source(frame);
  const cv::Mat* image = parts_.images.feature_image(frame, source);
  const bool have_depth = parts_.images.has_depth(frame);
  result.image_source = source;
  result.times.ms[kPreprocess] = elapsed_ms(stage_start);

  current_ = 0;
  while (current_ == reference_ || current_ == previous_) ++current_;
  extract(frame, image, source, have_depth, prior, result);

  new_reference_ = false;
  if (previous_ < 0) {
    result.status = FrameStatus::kFirstFrame;
    result.T_world_cam = Eigen::Isometry3d::Identity();
    new_reference_ = true;
    current_covariance_.setZero();
    step_covariance_.setZero();
    odom_covariance_.setZero();
    return;
  }
  const TrackedFrame& previous = frames_[static_cast<std::size_t>(previous_)];
  const TrackedFrame* target = register_current(frame, image, source, have_depth, prior, result);
  chain_covariance(target, target == &frames_[static_cast<std::size_t>(reference_)] ? reference_covariance_
                                                                                   : previous_covariance_,
                   result);
  motion_.finish(previous.T_world_cam, prior, result);
  chain_odom_covariance(target, prior, result);
}

void FeatureTracker::chain_odom_covariance(const TrackedFrame* target, const nav::MotionPrior* prior,
                                           const FrameResult& result) {
  const TrackedFrame& previous = frames_[static_cast<std::size_t>(previous_)];
  const bool wheels_carry = prior != nullptr && (result.wheels.fused || result.status == FrameStatus::kWheels);
  // Registered alone: the registration's own covariance on top of its target's. Where the wheels
  // joined the registration (the arbiter's covariance-weighted combination) or carried the frame,
  // the pose is the previous frame's moved by the wheel motion, corrected at most by vision: the
  // wheel prior's covariance bounds its step (the combination's is smaller; this is the bound).
  // Extrapolated (no registration, no wheels): the floor the tracker chains for such frames.
  const TrackedFrame& from = (target != nullptr && !wheels_carry) ? *target : previous;
  Matrix6d step = step_covariance_;
  if (target != nullptr && !wheels_carry) {
    // The a-posteriori variance factor (MSSE noise scale s, docs/methods.md §1): inliers that fit
    // s times worse than their predicted noise make the registration s² times less certain. The
    // registration's modelled information (the surfaces' and features' in fused mode) does not
    // include it; the pose graph's edges take it the same way (Backend::registration_information).
    step *= std::max(1.0, result.noise_scale * result.noise_scale);
    // A floor: the registration's translation is no more certain than one of its features'
    // predicted position noise (the median: the sensor's a·z² and the keypoint's, at the frame's
    // typical depth). The model's 1/n over the inliers presumes independent errors; depth errors
    // of the same wall and the same depth quantisation do not average out.
    const std::vector<float>& sigmas = frames_[static_cast<std::size_t>(current_)].features.sigma_m;
    if (!sigmas.empty()) {
      const std::size_t stride = (sigmas.size() + median_sample_.size() - 1) / median_sample_.size();
      std::size_t count = 0;
      for (std::size_t i = 0; i < sigmas.size() && count < median_sample_.size(); i += stride) median_sample_[count++] = sigmas[i];
      const auto middle = median_sample_.begin() + static_cast<std::ptrdiff_t>(count / 2);
      std::nth_element(median_sample_.begin(), middle, median_sample_.begin() + static_cast<std::ptrdiff_t>(count));
      const double floor_m = static_cast<double>(*middle);
      step.diagonal().tail<3>().array() += floor_m * floor_m;
    }
  }
  if (wheels_carry) {
    // The prior's ξ is on the left in the previous frame: exp(ξ)·T_p_c = T_p_c·exp(Ad(T_c_p)·ξ).
    const Matrix6d to_right = lie::adjoint((previous.T_world_cam.inverse() * result.T_world_cam).inverse());
    step = to_right * prior->covariance * to_right.transpose();
  }
  // T_w_f·Exp(ξ_f)·T_f_c·Exp(ξ) gives ξ_c = Ad(T_f_c⁻¹)·ξ_f + ξ.
  const Matrix6d carry = lie::adjoint((from.T_world_cam.inverse() * result.T_world_cam).inverse());
  const Matrix6d odom = carry * from.odom_covariance * carry.transpose() + step;
  odom_covariance_ = 0.5 * (odom + odom.transpose());
}

const FeatureTracker::TrackedFrame* FeatureTracker::register_current(const hal::RgbdFrame& frame,
                                                                     const cv::Mat* image, ImageSource source,
                                                                     bool have_depth, const nav::MotionPrior* prior,
                                                                     FrameResult& result) {
  const TrackedFrame& tracked = frames_[static_cast<std::size_t>(current_)];
  const TrackedFrame& previous = frames_[static_cast<std::size_t>(previous_)];
  const TrackedFrame& reference = frames_[static_cast<std::size_t>(reference_)];
  const Eigen::Isometry3d& predicted_step = motion_.predicted(prior);
  const Eigen::Isometry3d T_world_predicted = previous.T_world_cam * predicted_step;
  const geometry::GeometricFeatures* current_geometric = fused_ ? &tracked.geometric : nullptr;
  std::string_view reason;
  accepted_information_.setZero();
  // Fused mode registers on depth alone when the frame has no usable image.
  if (image == nullptr && !fused_) reason = "no usable image";
  if (!have_depth) reason = "no usable depth";
  const TrackedFrame* target = nullptr;
  // After a failed frame the prediction extrapolates the last motion, which may be the wrong
  // estimate that started the failure, and would reject good registrations as far from it. The
  // reference's pose was measured: a registration that sees it as well as tracked frames do
  // sets the pose again.
  const bool resuming = motion_.resuming(prior);
  motion_.set_resumed(false);
  bool poor_fit = false;
  if (reason.empty()) {
    if (reference.features.source == source) {
      const MotionEstimate estimate = parts_.registrar.register_frames(
          reference.features, reference.velocity, tracked.features, tracked.velocity, result,
          reference.T_world_cam.inverse() * T_world_predicted, reference.T_world_cam.inverse() * previous.T_world_cam,
          fused_ ? &reference.geometric : nullptr, current_geometric);
      if (motion_.accept(estimate, reference.T_world_cam, previous.T_world_cam, predicted_step, result.T_world_cam,
                         reason, resuming, reference_inliers_)) {
        target = &reference;
        accepted_information_ = estimate.information;
        motion_.set_resumed(resuming);
        result.resumed = resuming;
        // Overlap relative to the inliers the reference had with the first frame registered
        // against it: that count is what full overlap looks like for this scene and image kind.
        // A fraction of the reference's features would depend on how matchable the features
        // are, which differs widely between colour, IR and simulated images.
        if (reference_inliers_ == 0) reference_inliers_ = std::max(1, estimate.inliers);
        new_reference_ = estimate.inliers < config_.reference_min_overlap * reference_inliers_;
        poor_fit = !resuming && estimate.noise_scale > config_.reference_max_noise_scale;
      }
    } else if (const cv::Mat* bridge_image = parts_.images.feature_image(frame, reference.features.source);
               bridge_image != nullptr) {
      const auto stage_start = SteadyClock::now();
      orb_.extract(*bridge_image, frame.depth, bridge_, reference.features.source);
      result.times.ms[kFeatures] += elapsed_ms(stage_start);
      const MotionEstimate estimate = parts_.registrar.register_frames(
          reference.features, reference.velocity, bridge_, tracked.velocity, result,
          reference.T_world_cam.inverse() * T_world_predicted, reference.T_world_cam.inverse() * previous.T_world_cam,
          fused_ ? &reference.geometric : nullptr, current_geometric);
      if (motion_.accept(estimate, reference.T_world_cam, previous.T_world_cam, predicted_step, result.T_world_cam,
                         reason)) {
        target = &reference;
        accepted_information_ = estimate.information;
      }
      new_reference_ = true;  // the following frames need a reference of the new kind
    }
    // The previous frame is the fallback only: registering against it as well whenever the
    // overlap is low costs one more registration and is less accurate. A reference registration
    // whose inliers fit far worse than their noise says has lost the reference although its
    // inlier count has not dropped yet: the previous frame, closer in view, is registered too and
    // the better fit kept (and the frame becomes the reference).
    if ((target == nullptr || poor_fit) && previous_ != reference_ && previous.features.source == source) {
      const FrameResult from_reference = result;
      const MotionEstimate estimate = parts_.registrar.register_frames(
          previous.features, previous.velocity, tracked.features, tracked.velocity, result, predicted_step,
          Eigen::Isometry3d::Identity(), fused_ ? &previous.geometric : nullptr, current_geometric);
      if ((target == nullptr || estimate.noise_scale < from_reference.noise_scale) &&
          motion_.accept(estimate, previous.T_world_cam, previous.T_world_cam, predicted_step, result.T_world_cam,
                         reason)) {
        target = &previous;
        accepted_information_ = estimate.information;
        new_reference_ = true;
      } else if (target != nullptr) {
        const StageTimes times = result.times;
        result = from_reference;
        result.times = times;
      }
    }
  }
  if (target != nullptr && dense_) refine_dense(*target, result);
  if (target != nullptr && prior != nullptr &&
      !parts_.arbiter.arbitrate(*prior, previous.T_world_cam, result.inliers, result.T_world_cam, result.wheels)) {
    target = nullptr;
    reason = "registration disagrees with the wheels";
  }
  if (new_reference_ && target == &reference && result.wheels.fused &&
      std::abs(result.wheels.yaw_residual_deg) >= parts_.arbiter.least_slip_turn_deg()) {
    // The pose took the wheels' heading, not vision's: as the next frames' reference it would
    // hide a slip building up. The old reference still registers, so it stays.
    new_reference_ = false;
  }
  if (target != nullptr) {
    result.status = FrameStatus::kTracking;
  } else {
    result.status = prior != nullptr ? FrameStatus::kWheels : FrameStatus::kFailed;
    result.failure_reason = reason;
    new_reference_ = false;  // the reference stays: the next frame that sees it snaps back
  }
  return target;
}

void FeatureTracker::refine_dense(const TrackedFrame& target, FrameResult& result) {
  const auto stage_start = SteadyClock::now();
  const TrackedFrame& tracked = frames_[static_cast<std::size_t>(current_)];
  Eigen::Isometry3d T_cur_target = result.T_world_cam.inverse() * target.T_world_cam;
  const dense::DenseResult dense = dense_->align(target.dense, tracked.dense, T_cur_target);
  if (dense.ok) result.T_world_cam = lie::renormalised(target.T_world_cam * T_cur_target.inverse());
  result.times.ms[kDense] = elapsed_ms(stage_start);
}

void FeatureTracker::chain_covariance(const TrackedFrame* target, const Matrix6d& target_covariance,
                                      const FrameResult& result) {
  const Backend& backend = parts_.backend;
  if (target == nullptr) {
    // Not registered: the pose is extrapolated or the wheels'; a frame registered against it
    // later inherits no more than one floor's worth of confidence.
    step_covariance_ = lie::symmetric_inverse(backend.sequential_information_floor());
    current_covariance_ = target_covariance + step_covariance_;
    return;
  }
  const Matrix6d information =
      (accepted_information_.any()
           ? Matrix6d(accepted_information_)
           : backend.registration_information(std::max(result.inliers, config_.min_inliers), result.noise_scale)) +
      backend.sequential_information_floor();
  step_covariance_ = lie::symmetric_inverse(information);
  // T_K_c·exp(ξ_c) = T_K_t·exp(ξ_t)·T_t_c·exp(ξ) gives ξ_c = Ad(T_t_c⁻¹)·ξ_t + ξ.
  const Matrix6d carry = lie::adjoint((target->T_world_cam.inverse() * result.T_world_cam).inverse());
  current_covariance_ = carry * target_covariance * carry.transpose() + step_covariance_;
}

TrackedFeatures FeatureTracker::features() const {
  const TrackedFrame& tracked = frames_[static_cast<std::size_t>(current_)];
  return {&tracked.features, fused_ ? &tracked.geometric : nullptr, tracked.velocity};
}

Eigen::Matrix<double, 6, 6> FeatureTracker::keyframe_edge_information(const FrameResult& /*result*/) const {
  // As uncertain as the chain of registrations from the previous key-frame: a direction one weak
  // registration on the way left to the motion model (along a plain corridor) is weak in the
  // edge, so a loop closure's correction goes there.
  return lie::symmetric_inverse(current_covariance_);
}

void FeatureTracker::keyframe_stored() {
  current_covariance_.setZero();
  chain_restarted_ = true;
}

void FeatureTracker::correct(const Eigen::Isometry3d& correction) {
  for (TrackedFrame& tracked : frames_) tracked.T_world_cam = lie::renormalised(correction * tracked.T_world_cam);
}

void FeatureTracker::relocalise(const Eigen::Isometry3d& T_world_cam, const Matrix6d& covariance,
                                FrameResult& result) {
  result.T_world_cam = T_world_cam;
  result.status = FrameStatus::kTracking;
  result.failure_reason = {};
  motion_.relocalised(T_world_cam);
  new_reference_ = true;
  chain_restarted_ = false;
  // The pose is the key-frame's moved by one registration: as certain as that registration. The
  // odom pose's chain goes on (the jump is the map frame's).
  step_covariance_ = covariance;
  current_covariance_ = covariance;
}

void FeatureTracker::end_frame(FrameResult& result) {
  frames_[static_cast<std::size_t>(current_)].T_world_cam = result.T_world_cam;
  frames_[static_cast<std::size_t>(current_)].odom_covariance = odom_covariance_;
  result.odom_covariance = odom_covariance_;
  result.odom_covariance_valid = true;
  if (chain_restarted_ && !new_reference_ && previous_ >= 0) {
    // The reference is older than the key-frame this frame became: its pose relative to the
    // key-frame is the inverse of this frame's registration, T_K_r = (T_r_K·exp(b))⁻¹ =
    // T_K_r·exp(−Ad(T_r_K)·b).
    const Matrix6d carry =
        lie::adjoint(frames_[static_cast<std::size_t>(reference_)].T_world_cam.inverse() * result.T_world_cam);
    reference_covariance_ = carry * step_covariance_ * carry.transpose();
  }
  previous_covariance_ = current_covariance_;
  if (new_reference_) {
    reference_ = current_;
    reference_inliers_ = 0;
    reference_covariance_ = current_covariance_;
  }
  previous_ = current_;
  result.new_reference = new_reference_;
}

}  // namespace rankslam::slam
