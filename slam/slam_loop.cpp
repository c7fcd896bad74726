#include "rankslam/slam/slam_loop.hpp"
#include "rankslam/core/units.hpp"

#include "rankslam/slam/registration_support.hpp"

#include <Eigen/Cholesky>
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

using enum StageTimes::Stage;

// The colour image must brighten to this multiple of the switch threshold before features
// return to it: a scene hovering at the threshold would otherwise flip image kinds every few
// frames, and each switch costs a second feature extraction.
constexpr double kColourReturnFactor = 1.25;

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

bool valid_image(const cv::Mat& image, int type, int width, int height) {
  return image.type() == type && image.cols == width && image.rows == height;
}

using lie::Matrix6d;

}  // namespace

SlamLoop::SlamLoop(const SlamConfig& config, const hal::Calibration& calibration)
    : config_(config),
      camera_(calibration.rgb, calibration.depth_scale),
      orb_(config_, camera_),
      infrared_orb_(config_, camera_, config_.ir_orb_fast_threshold),
      map_(config.map_voxel_m, static_cast<std::size_t>(config.map_max_points)),
      infrared_filter_(camera_.width(), camera_.height()),
      icp_(icp_settings(config_), camera_),
      registrar_(config_, camera_, calibration.rgb.T_base_cam, calibration.wheels.has_value(), companion_, geometric_),
      arbiter_(config.wheels, calibration.rgb.T_base_cam),
      map_sampler_(static_cast<std::mt19937::result_type>(config.seed)),
      keyframe_store_(config.keyframe_capacity,
                      config.mode == Mode::kGeometric ? 0 : static_cast<std::size_t>(config.orb_features) * 2,
                      config.mode == Mode::kGeometric || config.mode == Mode::kFused ? config.geometry.max_keypoints : 0,
                      config.mode == Mode::kFused ? config.keyframe_cloud_points : 0,
                      config.map_points_per_keyframe),
      backend_(config_, calibration.rgb.T_base_cam, calibration.wheels.has_value()),
      loop_closer_(config_, keyframe_store_, registrar_, geometric_, backend_) {
  const auto capacity = static_cast<std::size_t>(config.orb_features) * 2;
  for (auto& tracked : frames_) {
    tracked.features.reserve(capacity);
    if (config_.icp_mode != IcpMode::kOff) {
      tracked.cloud.points.reserve(icp_.cloud_capacity());
      tracked.cloud.normals.reserve(icp_.cloud_capacity());
    }
  }
  bridge_.reserve(capacity);
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
  registrar_.share_with(&team_);
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
      loop_closer_.keep_features_in(geometric_.make_features());  // a search may carry over into later frames
    }
    registrar_.size_geometric_matches();
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
      // frame since then. (Without it, a plain corridor's end wall registered turned around
      // after a single failed frame.)
      const Eigen::Isometry3d since_tracked = T_world_last_tracked_.inverse() * T_world_candidate;
      const double frames_since_tracked = failed_in_a_row_ + 1.0;
      if (since_tracked.translation().norm() > frames_since_tracked * config_.max_deviation_translation_m ||
          lie::rotation_deg(since_tracked) > frames_since_tracked * config_.max_deviation_rotation_deg) {
        why = "motion since the last tracked frame far from any the camera can have made";
      }
    } else {
      const Eigen::Isometry3d step = T_world_previous.inverse() * T_world_candidate;
      const Eigen::Isometry3d deviation = predicted_step.inverse() * step;
      if (step.translation().norm() > config_.max_step_translation_m ||
          lie::rotation_deg(step) > config_.max_step_rotation_deg) {
        why = "implausible frame-to-frame motion";
      } else if (deviation.translation().norm() > config_.max_deviation_translation_m ||
                 lie::rotation_deg(deviation) > config_.max_deviation_rotation_deg) {
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
        lie::rotation_deg(correction) <= config_.icp_max_correction_deg) {
      result.T_world_cam = target.T_world_cam * refined.T_target_source;
      result.icp_refined = true;
    }
  }
  result.times.ms[kIcp] += elapsed_ms(stage_start);
}

FrameResult SlamLoop::process(const hal::RgbdFrame& frame) { return process(frame, nullptr); }

FrameResult SlamLoop::process(const hal::RgbdFrame& frame, const nav::MotionPrior* prior) {
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
  // (fr1_rpy_head features stage, docs/results.md §2.3).
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
    // estimate that started the failure, and would reject good registrations as far from it. The
    // reference's pose was measured: a registration that sees it as well as tracked frames do
    // sets the pose again.
    const bool resuming = failed_in_a_row_ > 0 && prior == nullptr;
    resumed_tracking_ = false;
    bool poor_fit = false;
    if (reason.empty()) {
      if (reference.features.source == source) {
        const MotionEstimate estimate = registrar_.register_frames(
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
          // are, which differs widely between colour, IR and simulated images.
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
        const MotionEstimate estimate = registrar_.register_frames(
            reference.features, reference.velocity, bridge_, tracked.velocity, result,
            reference.T_world_cam.inverse() * T_world_predicted, reference.T_world_cam.inverse() * previous.T_world_cam,
            fused ? &reference.geometric : nullptr, fused ? &tracked.geometric : nullptr);
        if (accept(estimate, reference.T_world_cam, previous.T_world_cam, predicted_step, result.T_world_cam, reason)) {
          target = &reference;
          accepted_information_ = estimate.information;
        }
        new_reference = true;  // the following frames need a reference of the new kind
      }
      // Registering against the previous frame as well whenever the overlap is low, keeping the
      // result with more inliers, costs one more registration and is less accurate: the previous
      // frame is the fallback only.
      // A reference registration whose inliers fit far worse than their noise says has lost the
      // reference although its inlier count has not dropped yet: the previous frame, closer in
      // view, is registered too and the better fit kept (and the frame becomes the reference).
      if ((target == nullptr || poor_fit) && previous_ != reference_ && previous.features.source == source) {
        const FrameResult from_reference = result;
        const MotionEstimate estimate =
            registrar_.register_frames(previous.features, previous.velocity, tracked.features, tracked.velocity, result,
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
      if (prior != nullptr && !arbiter_.arbitrate(*prior, previous.T_world_cam, result.inliers, result.T_world_cam, result.wheels)) {
        target = nullptr;
        reason = "registration disagrees with the wheels";
      }
    }
    if (new_reference && target == &reference && result.wheels.fused &&
        std::abs(result.wheels.yaw_residual_deg) >= arbiter_.least_slip_turn_deg()) {
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
        lie::adjoint(frames_[static_cast<std::size_t>(reference_)].T_world_cam.inverse() * result.T_world_cam);
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
                            const nav::MotionPrior* prior, FrameResult& result) {
  backend_.accumulate_wheel_motion(prior);
  if (!result.wheels.compared) {
    // The window and the runs count consecutive compared frames only.
    arbiter_.interrupt();
  }
  if (result.status == FrameStatus::kTracking) {
    result.T_world_cam = lie::renormalised(result.T_world_cam);
    // A frame that resumed tracking jumped from an extrapolated pose: that is no motion to go on
    // with, so the next prediction holds the pose.
    last_motion_ = resumed_tracking_ ? Eigen::Isometry3d::Identity() : lie::renormalised(T_world_previous.inverse() * result.T_world_cam);
    T_world_last_tracked_ = result.T_world_cam;
    failed_in_a_row_ = 0;
  } else if (result.status == FrameStatus::kWheels && prior != nullptr) {
    // The wheels carry the pose; their motion is also the best constant-velocity model should
    // the next frame come without a prior.
    last_motion_ = prior->T_previous_current;
    result.T_world_cam = lie::renormalised(T_world_previous * last_motion_);
    T_world_last_tracked_ = result.T_world_cam;
    failed_in_a_row_ = 0;
  } else if (result.status == FrameStatus::kFailed) {
    // Constant-velocity extrapolation keeps the pose continuous through a short gap; a long gap
    // holds the pose instead (see max_extrapolated_frames).
    if (++failed_in_a_row_ > config_.max_extrapolated_frames) last_motion_ = Eigen::Isometry3d::Identity();
    result.T_world_cam = lie::renormalised(T_world_previous * last_motion_);
  }

  const auto stage_start = Clock::now();
  const Eigen::Isometry3d since_keyframe = T_world_last_keyframe_.inverse() * result.T_world_cam;
  if (result.status == FrameStatus::kFirstFrame ||
      (result.status == FrameStatus::kTracking &&
       (since_keyframe.translation().norm() > config_.keyframe_translation_m ||
        lie::rotation_deg(since_keyframe) > config_.keyframe_rotation_deg))) {
    T_world_last_keyframe_ = result.T_world_cam;
    result.keyframe = true;
    ++keyframes_;
    store_keyframe(frame, have_depth, result);
  }
  loop_closer_.advance(config_.loop_candidates_per_frame, result);
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
    backend_.remove_node(keyframe_store_.slot(slot).node);
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
  keyframe.node = backend_.add_node(keyframe.T_world_cam, keyframe.generation);
  if (latest_keyframe_slot_ >= 0 && latest_keyframe_slot_ != slot) {
    const StoredKeyframe& previous = keyframe_store_.slot(latest_keyframe_slot_);
    const Eigen::Isometry3d T_previous_current = previous.T_world_cam.inverse() * keyframe.T_world_cam;
    path_m_ += T_previous_current.translation().norm();
    if (previous.used && previous.node >= 0 && keyframe.node >= 0) {
      Matrix6d information;
      if (config_.mode != Mode::kGeometric) {
        // As uncertain as the chain of registrations from the previous key-frame: a direction
        // one weak registration on the way left to the motion model (along a plain corridor) is
        // weak in the edge, so a loop closure's correction goes there.
        information = lie::symmetric_inverse(current_covariance_);
      } else {
        information = backend_.registration_information(std::max(result.inliers, config_.min_inliers), result.noise_scale);
      }
      backend_.add_sequential_edges(previous.node, keyframe.node, T_previous_current, information);
    }
  }
  backend_.restart_wheel_motion();
  current_covariance_.setZero();
  chain_restarted_ = true;
  keyframe.path_m = path_m_;
  if (have_depth) add_keyframe_to_map(frame, result.T_world_cam, &keyframe);
  latest_keyframe_slot_ = slot;
  // A search still under way for the previous key-frame ends before this one's starts.
  loop_closer_.advance(0, result);
  if (result.status == FrameStatus::kTracking && keyframe.node >= 0) loop_closer_.start(slot, current_geometric_);
}

void SlamLoop::chain_covariance(const TrackedFrame* target, const Matrix6d& target_covariance,
                                const FrameResult& result) {
  if (target == nullptr) {
    // Not registered: the pose is extrapolated or the wheels'; a frame registered against it
    // later inherits no more than one floor's worth of confidence.
    step_covariance_ = lie::symmetric_inverse(backend_.sequential_information_floor());
    current_covariance_ = target_covariance + step_covariance_;
    return;
  }
  const Matrix6d information =
      (accepted_information_.any()
           ? Matrix6d(accepted_information_)
           : backend_.registration_information(std::max(result.inliers, config_.min_inliers), result.noise_scale)) +
      backend_.sequential_information_floor();
  step_covariance_ = lie::symmetric_inverse(information);
  // T_K_c·exp(ξ_c) = T_K_t·exp(ξ_t)·T_t_c·exp(ξ) gives ξ_c = Ad(T_t_c⁻¹)·ξ_t + ξ.
  const Matrix6d carry = lie::adjoint((target->T_world_cam.inverse() * result.T_world_cam).inverse());
  current_covariance_ = carry * target_covariance * carry.transpose() + step_covariance_;
}

void SlamLoop::run_backend(FrameResult& result) {
  backend_.submit_pending();
  Eigen::Isometry3d correction;
  if (!backend_.take_solve(keyframe_store_, correction)) return;
  correct_tracking(correction);
  result.T_world_cam = lie::renormalised(correction * result.T_world_cam);
  result.graph_applied = true;
  result.map_correction = lie::renormalised(correction * result.map_correction);
}

void SlamLoop::correct_tracking(const Eigen::Isometry3d& correction) {
  for (TrackedFrame& tracked : frames_) tracked.T_world_cam = lie::renormalised(correction * tracked.T_world_cam);
  T_world_last_keyframe_ = lie::renormalised(correction * T_world_last_keyframe_);
  T_world_geometric_previous_ = lie::renormalised(correction * T_world_geometric_previous_);
  T_world_geometric_target_ = lie::renormalised(correction * T_world_geometric_target_);
}

void SlamLoop::finish() {
  {
    FrameResult ignored;
    loop_closer_.advance(0, ignored);
  }
  backend_.finish(keyframe_store_, [this](const Eigen::Isometry3d& correction) { correct_tracking(correction); });
  if (loop_closer_.closures() == 0) return;  // the live map already sits on the only poses there are
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

FrameResult SlamLoop::process_geometric(const hal::RgbdFrame& frame, const nav::MotionPrior* prior) {
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
          !arbiter_.arbitrate(*prior, T_world_geometric_previous_, descriptor_inliers, result.T_world_cam, result.wheels)) {
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
