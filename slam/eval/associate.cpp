#include "rankslam/eval/associate.hpp"

namespace rankslam::eval {

std::vector<StampMatch> associate(const Trajectory& first, const Trajectory& second,
                                  double max_difference_s) {
  std::vector<double> first_stamps_s(first.size());
  std::vector<double> second_stamps_s(second.size());
  for (std::size_t i = 0; i < first.size(); ++i) first_stamps_s[i] = first[i].stamp_s;
  for (std::size_t i = 0; i < second.size(); ++i) second_stamps_s[i] = second[i].stamp_s;
  return associate(std::span<const double>(first_stamps_s),
                   std::span<const double>(second_stamps_s), max_difference_s);
}

}  // namespace rankslam::eval
