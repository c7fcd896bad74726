#pragma once

// Polynomial arc functions for the per-neighbour loops (SHOT bins, ROS angles), where the libm
// calls would cost more than everything else together. Errors are far below what the
// quantities they feed can resolve (histogram interpolation weights, noisy normal angles).

#include <algorithm>
#include <cmath>

namespace rankslam::geometry::detail {

inline constexpr double kPi = 3.14159265358979323846;

/// arccos(x) for x in [−1, 1] (clamped); |error| ≤ 2·10⁻⁸ rad (Abramowitz & Stegun 4.4.46).
template <class T>
inline T fast_acos(T x) {
  x = std::clamp(x, T(-1), T(1));
  const T a = std::abs(x);
  const T p =
      T(1.5707963050) +
      a * (T(-0.2145988016) +
           a * (T(0.0889789874) +
                a * (T(-0.0501743046) +
                     a * (T(0.0308918810) +
                          a * (T(-0.0170881256) + a * (T(0.0066700901) + a * T(-0.0012624911)))))));
  const T r = std::sqrt(T(1) - a) * p;
  return x >= T(0) ? r : T(kPi) - r;
}

/// atan2(y, x) in (−π, π]; |error| ≤ 10⁻⁵ rad (odd minimax polynomial of atan on [−1, 1]).
template <class T>
inline T fast_atan2(T y, T x) {
  const T ax = std::abs(x);
  const T ay = std::abs(y);
  if (ax == T(0) && ay == T(0)) return T(0);
  const bool swap = ay > ax;
  const T t = swap ? ax / ay : ay / ax;
  const T t2 = t * t;
  T r = t * (T(0.99997726) +
             t2 * (T(-0.33262347) +
                   t2 * (T(0.19354346) +
                         t2 * (T(-0.11643287) + t2 * (T(0.05265332) + t2 * T(-0.01172120))))));
  if (swap) r = T(kPi / 2) - r;
  if (x < T(0)) r = T(kPi) - r;
  return y < T(0) ? -r : r;
}

}  // namespace rankslam::geometry::detail
