#include "rankslam/sim/motion.hpp"

#include "rankslam/core/units.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace rankslam::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// Cosine ramp up, plateau, cosine ramp down, covering |amount| at a peak rate.
struct RateProfile {
  double peak = 0.0;
  double ramp_s = 0.0;
  double plateau_s = 0.0;

  static RateProfile make(double amount, double peak_rate, double ramp_s) {
    RateProfile profile;
    profile.ramp_s = std::max(ramp_s, 1e-6);
    const double magnitude = std::abs(amount);
    // The two ramps alone cover peak·ramp; a shorter move lowers the peak instead.
    profile.peak = std::min(peak_rate, magnitude / profile.ramp_s);
    profile.plateau_s = profile.peak > 0.0 ? (magnitude - profile.peak * profile.ramp_s) / profile.peak : 0.0;
    return profile;
  }
  [[nodiscard]] double duration_s() const { return 2.0 * ramp_s + plateau_s; }
  // Distance covered after t seconds.
  [[nodiscard]] double progress(double t) const {
    const double w = kPi / ramp_s;
    if (t <= 0.0) return 0.0;
    if (t < ramp_s) return 0.5 * peak * (t - std::sin(w * t) / w);
    const double up = 0.5 * peak * ramp_s;
    if (t < ramp_s + plateau_s) return up + peak * (t - ramp_s);
    const double td = std::min(t - ramp_s - plateau_s, ramp_s);
    return up + peak * plateau_s + 0.5 * peak * (td + std::sin(w * td) / w);
  }
  [[nodiscard]] double rate(double t) const {
    const double w = kPi / ramp_s;
    if (t <= 0.0 || t >= duration_s()) return 0.0;
    if (t < ramp_s) return 0.5 * peak * (1.0 - std::cos(w * t));
    if (t < ramp_s + plateau_s) return peak;
    return 0.5 * peak * (1.0 + std::cos(w * (t - ramp_s - plateau_s)));
  }
};

RateProfile profile_of(const DriveSegment& segment) {
  return RateProfile::make(segment.amount, segment.peak_rate, segment.ramp_s);
}

}  // namespace

double HarmonicSignal::value(double t_s, double period_s) const {
  double sum = offset;
  const double w = 2.0 * kPi / period_s;
  for (const auto& term : terms) sum += term.amplitude * std::sin(w * term.multiple * t_s + term.phase_rad);
  return sum;
}

Eigen::Isometry3d HandheldMotion::T_world_cam(double t_s) const {
  const Eigen::Vector3d p(position_m[0].value(t_s, period_s), position_m[1].value(t_s, period_s),
                          position_m[2].value(t_s, period_s));
  const Eigen::Vector3d target(target_m[0].value(t_s, period_s), target_m[1].value(t_s, period_s),
                               target_m[2].value(t_s, period_s));
  const Eigen::Vector3d z = (target - p).normalized();
  const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
  const Eigen::Vector3d y = z.cross(x);
  Eigen::Matrix3d R;
  R << x, y, z;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R * Eigen::AngleAxisd(roll_rad.value(t_s, period_s), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = p;
  return T;
}

DriveMotion::DriveMotion(Eigen::Vector2d start_xy_m, double start_heading_rad, std::vector<DriveSegment> segments)
    : segments_(std::move(segments)) {
  SegmentStart start;
  start.xy_m = start_xy_m;
  start.heading_rad = start_heading_rad;
  starts_.push_back(start);
  for (const auto& segment : segments_) {
    SegmentStart next = start;
    if (segment.kind == DriveSegment::Kind::kStraight) {
      next.xy_m += segment.amount * Eigen::Vector2d(std::cos(start.heading_rad), std::sin(start.heading_rad));
      next.distance_m += segment.amount;
      next.t_s += profile_of(segment).duration_s();
    } else if (segment.kind == DriveSegment::Kind::kTurn) {
      next.heading_rad += segment.amount;
      next.t_s += profile_of(segment).duration_s();
    } else {
      next.t_s += std::max(segment.amount, 0.0);
    }
    starts_.push_back(next);
    start = next;
  }
  period_s_ = starts_.back().t_s;
}

double DriveMotion::segment_duration_s(std::size_t i) const { return starts_[i + 1].t_s - starts_[i].t_s; }

DriveState DriveMotion::state(double t_s) const {
  DriveState state;
  if (segments_.empty() || !(period_s_ > 0.0)) {
    if (!starts_.empty()) {
      state.xy_m = starts_.front().xy_m;
      state.heading_rad = wrap_angle(starts_.front().heading_rad);
    }
    return state;
  }
  const double loops = std::floor(t_s / period_s_);
  double local = t_s - loops * period_s_;
  local = std::clamp(local, 0.0, period_s_);
  // Last segment whose start is not after `local`.
  const auto it = std::upper_bound(starts_.begin(), starts_.end() - 1, local,
                                   [](double t, const SegmentStart& s) { return t < s.t_s; });
  const std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(0, (it - starts_.begin()) - 1));
  const SegmentStart& start = starts_[std::min(i, segments_.size() - 1)];
  const DriveSegment& segment = segments_[std::min(i, segments_.size() - 1)];
  const double tau = local - start.t_s;
  const double loop_distance = starts_.back().distance_m - starts_.front().distance_m;
  const double loop_turn = starts_.back().heading_rad - starts_.front().heading_rad;

  state.xy_m = start.xy_m;
  double heading = start.heading_rad;
  double distance = start.distance_m;
  if (segment.kind != DriveSegment::Kind::kPause) {
    const RateProfile profile = profile_of(segment);
    const double sign = segment.amount < 0.0 ? -1.0 : 1.0;
    const double progress = sign * profile.progress(tau);
    const double rate = sign * profile.rate(tau);
    if (segment.kind == DriveSegment::Kind::kStraight) {
      state.xy_m += progress * Eigen::Vector2d(std::cos(heading), std::sin(heading));
      distance += progress;
      state.speed_mps = rate;
      state.straight = tau >= profile.ramp_s && tau <= profile.ramp_s + profile.plateau_s;
    } else {
      heading += progress;
      state.yaw_rate_rps = rate;
    }
  }
  state.heading_rad = wrap_angle(heading);
  state.distance_m = loops * loop_distance + distance - starts_.front().distance_m;
  state.turned_rad = loops * loop_turn + heading - starts_.front().heading_rad;
  return state;
}

Eigen::Isometry3d DriveMotion::T_world_base(double t_s) const {
  const DriveState s = state(t_s);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(s.heading_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(s.xy_m.x(), s.xy_m.y(), 0.0);
  return T;
}

double DriveMotion::closure_error_m() const {
  if (starts_.empty()) return 0.0;
  return (starts_.back().xy_m - starts_.front().xy_m).norm();
}

}  // namespace rankslam::sim
