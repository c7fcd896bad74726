#pragma once

#include <Eigen/Geometry>

#include <array>
#include <vector>

namespace rankslam::sim {

/// offset + Σ amplitude·sin(2π·multiple·t/period + phase): periodic in the period by design.
struct HarmonicSignal {
  struct Term {
    int multiple = 1;
    double amplitude = 0.0;
    double phase_rad = 0.0;
  };
  double offset = 0.0;
  std::vector<Term> terms;

  [[nodiscard]] double value(double t_s, double period_s) const;
};

/// Hand-held camera: position and a look-at target as harmonic signals, plus a roll about the
/// optical axis. Repeats every period_s.
struct HandheldMotion {
  double period_s = 10.0;
  std::array<HarmonicSignal, 3> position_m;  ///< World x, y, z of the optical centre.
  std::array<HarmonicSignal, 3> target_m;    ///< World point on the optical axis.
  HarmonicSignal roll_rad;                   ///< Rotation about the optical axis.

  /// Optical frame (x right, y down, z forward) in the world (z up).
  [[nodiscard]] Eigen::Isometry3d T_world_cam(double t_s) const;
};

/// One piece of a differential-drive plan. Rates follow a cosine ramp up, a plateau at the
/// peak rate and a cosine ramp down, so speed and yaw rate are continuous.
struct DriveSegment {
  enum class Kind { kStraight, kTurn, kPause };
  Kind kind = Kind::kPause;
  double amount = 0.0;     ///< Straight: signed metres. Turn: signed radians (left positive). Pause: seconds.
  double peak_rate = 0.0;  ///< Straight: m/s. Turn: rad/s. Positive.
  double ramp_s = 1.0;     ///< Duration of each cosine ramp.
};

/// Where a differential-drive robot is at one time.
struct DriveState {
  Eigen::Vector2d xy_m = Eigen::Vector2d::Zero();
  double heading_rad = 0.0;  ///< Wrapped to [-π, π).
  double distance_m = 0.0;   ///< Signed distance driven since t = 0 (all loops).
  double turned_rad = 0.0;   ///< Signed heading change since t = 0, not wrapped (all loops).
  double speed_mps = 0.0;
  double yaw_rate_rps = 0.0;
  bool straight = false;     ///< Inside a straight segment's plateau (cruising).
};

/// A closed plan of straight runs, turns in place and pauses on the floor plane, repeated
/// forever. Poses are analytic: no integration error.
class DriveMotion {
 public:
  DriveMotion() = default;
  DriveMotion(Eigen::Vector2d start_xy_m, double start_heading_rad, std::vector<DriveSegment> segments);

  [[nodiscard]] double period_s() const { return period_s_; }
  [[nodiscard]] const std::vector<DriveSegment>& segments() const { return segments_; }
  /// Start time of segment i within one period.
  [[nodiscard]] double segment_start_s(std::size_t i) const { return starts_[i].t_s; }
  [[nodiscard]] double segment_duration_s(std::size_t i) const;
  [[nodiscard]] DriveState state(double t_s) const;
  /// Robot base frame (x forward, y left, z up, origin on the floor) in the world.
  [[nodiscard]] Eigen::Isometry3d T_world_base(double t_s) const;
  /// Distance from the end pose of one loop to its start pose (0 for a closed plan).
  [[nodiscard]] double closure_error_m() const;

 private:
  struct SegmentStart {
    double t_s = 0.0;
    Eigen::Vector2d xy_m = Eigen::Vector2d::Zero();
    double heading_rad = 0.0;
    double distance_m = 0.0;
  };
  std::vector<DriveSegment> segments_;
  std::vector<SegmentStart> starts_;  // segments_.size() + 1 entries; the last is the loop end
  double period_s_ = 0.0;
};

}  // namespace rankslam::sim
