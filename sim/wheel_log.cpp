#include "wheel_log.hpp"

#include "random.hpp"

#include "rankslam/hal/candump.hpp"
#include "rankslam/nav/wheel_frame.hpp"

#include <cmath>
#include <numbers>
#include <vector>

namespace rankslam::sim::detail {
namespace {

constexpr double kTickJitterSigma = 0.35;  // counter read jitter, ticks (does not accumulate)

struct WheelTravel {
  double left_m = 0.0;
  double right_m = 0.0;
};

WheelTravel travel(const DriveMotion& motion, double track_width_m, double t_s) {
  const DriveState s = motion.state(t_s);
  return {s.distance_m - 0.5 * track_width_m * s.turned_rad, s.distance_m + 0.5 * track_width_m * s.turned_rad};
}

// Slips of loop `loop`: in some straight runs (while cruising), one wheel spins for a moment.
void plan_slips(const DriveMotion& motion, std::uint64_t seed, int loop, double period_s, double frame_s,
                std::vector<SlipSegment>& slips, std::int64_t start_stamp_ns) {
  Rng rng(mix64(seed ^ 0x511b5e9dULL) + static_cast<std::uint64_t>(loop));
  const auto& segments = motion.segments();
  bool any = false;
  for (int pass = 0; pass < 2 && !any; ++pass) {
    for (std::size_t i = 0; i < segments.size(); ++i) {
      const DriveSegment& seg = segments[i];
      if (seg.kind != DriveSegment::Kind::kStraight) continue;
      const double cruise_start = motion.segment_start_s(i) + seg.ramp_s;
      const double cruise_s = motion.segment_duration_s(i) - 2.0 * seg.ramp_s;
      if (cruise_s < 2.5) continue;
      // A second pass forces one slip so every loop has at least one.
      if (!(pass == 1 || rng.chance(0.6))) continue;
      const double start = loop * period_s + cruise_start + rng.uniform(0.5, cruise_s - 1.2);
      const double duration = rng.uniform(0.2, 0.6);
      SlipSegment slip;
      const auto start_frame = static_cast<std::int64_t>(std::llround(start / frame_s));
      const auto end_frame = start_frame + std::max<std::int64_t>(1, std::llround(duration / frame_s));
      slip.start_ns = start_stamp_ns + static_cast<std::int64_t>(std::llround(start_frame * frame_s * 1e9));
      slip.end_ns = start_stamp_ns + static_cast<std::int64_t>(std::llround(end_frame * frame_s * 1e9));
      slip.wheel = rng.chance(0.5) ? 1 : 0;
      slip.over_count = rng.uniform(0.15, 0.4);
      slips.push_back(slip);
      any = true;
      if (pass == 1) break;
    }
  }
}

}  // namespace

void build_wheel_log(const DriveMotion& motion, const hal::WheelGeometry& wheels, const WheelLogOptions& options,
                     std::string& can_log, std::vector<SlipSegment>& slips) {
  can_log.clear();
  slips.clear();
  const double frame_s = 1.0 / options.rate_hz;
  const auto frame_ns = static_cast<std::int64_t>(std::llround(1e9 / options.rate_hz));
  const auto first = static_cast<std::int64_t>(std::ceil(options.begin_s / frame_s - 1e-9));
  const auto last = static_cast<std::int64_t>(std::floor(options.end_s / frame_s + 1e-9));
  const double period = motion.period_s();
  // Slips are planned per loop from time 0, so the counters of a later stretch include the
  // slips before it and the same stretch always reads the same.
  std::vector<SlipSegment> planned;
  if (options.slip && period > 0.0) {
    const int loops = static_cast<int>(std::ceil(options.end_s / period)) + 1;
    for (int loop = 0; loop < loops; ++loop) plan_slips(motion, options.seed, loop, period, frame_s, planned, options.epoch_ns);
  }
  // Listed: the slips that overlap the written stretch.
  const std::int64_t last_stamp_ns = options.epoch_ns + last * frame_ns;
  const std::int64_t first_stamp_ns = options.epoch_ns + first * frame_ns;
  for (const auto& slip : planned) {
    if (slip.start_ns < last_stamp_ns && slip.end_ns > first_stamp_ns) slips.push_back(slip);
  }
  Rng rng(mix64(options.seed ^ 0xe7c0de5ULL));
  const double ticks_per_m = wheels.ticks_per_revolution / (2.0 * std::numbers::pi * wheels.radius_m);
  // Left counter wraps within the first metre and a half; the right one starts anywhere.
  const double offset_left = static_cast<double>(nav::kWheelTickModulus) - 20000.0 + rng.integer(0, 5000);
  const double offset_right = rng.integer(0, static_cast<int>(nav::kWheelTickModulus) - 1);
  auto rolling = static_cast<std::uint8_t>(rng.integer(0, 255));
  double extra_left = 0.0;
  double extra_right = 0.0;
  WheelTravel previous = travel(motion, wheels.track_width_m, 0.0);
  can_log.reserve(static_cast<std::size_t>(std::max<std::int64_t>(last - first + 1, 0)) * 48);
  for (std::int64_t k = 0; k <= last; ++k) {
    const double t = static_cast<double>(k) * frame_s;
    const std::int64_t stamp_ns = options.epoch_ns + k * frame_ns;
    const WheelTravel now = travel(motion, wheels.track_width_m, t);
    // Slip: during (start, end] the slipping wheel reports more rotation than it rolled.
    for (const auto& slip : planned) {
      if (stamp_ns > slip.start_ns && stamp_ns <= slip.end_ns) {
        if (slip.wheel == 0) {
          extra_left += slip.over_count * std::abs(now.left_m - previous.left_m);
        } else {
          extra_right += slip.over_count * std::abs(now.right_m - previous.right_m);
        }
      }
    }
    previous = now;
    double left = offset_left + (now.left_m + extra_left) * ticks_per_m;
    double right = offset_right + (now.right_m + extra_right) * ticks_per_m;
    if (options.tick_noise) {
      left += kTickJitterSigma * rng.gaussian();
      right += kTickJitterSigma * rng.gaussian();
    }
    const auto wrap = [](double ticks) {
      const auto m = static_cast<std::int64_t>(nav::kWheelTickModulus);
      const auto value = static_cast<std::int64_t>(std::floor(ticks)) % m;
      return static_cast<std::uint32_t>(value < 0 ? value + m : value);
    };
    nav::WheelTicks ticks;
    ticks.left_ticks = wrap(left);
    ticks.right_ticks = wrap(right);
    ticks.rolling_counter = rolling++;
    // Frames before the stretch are generated too (they advance the noise, slip and rolling
    // counter state) but not written.
    if (k < first) continue;
    can_log += hal::format_candump_line(nav::encode_wheel_ticks(ticks, wheels.can_id, stamp_ns), "can0");
    can_log += '\n';
  }
}

}  // namespace rankslam::sim::detail
