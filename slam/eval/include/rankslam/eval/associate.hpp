#pragma once

#include <span>
#include <vector>

#include "rankslam/eval/trajectory.hpp"
#include "rankslam/hal/associate.hpp"

namespace rankslam::eval {

// The TUM benchmark's stamp association lives in the HAL, shared with the replay reader.
using hal::kDefaultMaxDifference_s;
using hal::StampMatch;

/// hal::associate_stamps() (exactly the TUM benchmark's associate.py) under the evaluation
/// library's name.
[[nodiscard]] inline std::vector<StampMatch> associate(std::span<const double> first_stamps_s,
                                                       std::span<const double> second_stamps_s,
                                                       double max_difference_s = kDefaultMaxDifference_s) {
  return hal::associate_stamps(first_stamps_s, second_stamps_s, max_difference_s);
}

/// associate() on the stamps of two trajectories.
[[nodiscard]] std::vector<StampMatch> associate(const Trajectory& first, const Trajectory& second,
                                                double max_difference_s = kDefaultMaxDifference_s);

}  // namespace rankslam::eval
