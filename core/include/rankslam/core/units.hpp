#pragma once

// Angle units and wrapping, written once for every part.

#include <cmath>
#include <numbers>

namespace rankslam {

[[nodiscard]] constexpr double deg_to_rad(double deg) { return deg * std::numbers::pi / 180.0; }
[[nodiscard]] constexpr double rad_to_deg(double rad) { return rad * 180.0 / std::numbers::pi; }

/// `angle_rad` wrapped into [-π, π).
[[nodiscard]] inline double wrap_angle(double angle_rad) {
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  double wrapped = angle_rad - kTwoPi * std::floor((angle_rad + std::numbers::pi) / kTwoPi);
  // Rounding can land exactly on +π for inputs just below it.
  if (wrapped >= std::numbers::pi) wrapped -= kTwoPi;
  return wrapped;
}

}  // namespace rankslam
