#include "rankslam/robust/workspace.hpp"

#include <algorithm>
#include <cstddef>

namespace rankslam::robust {

void RobustWorkspace::reserve(int max_points) {
  const auto n = static_cast<std::size_t>(std::max(0, max_points));
  scores_.assign(n, 0.0);
  sq_residuals_.assign(n, 0.0);
  inverse_variances_.assign(n, 1.0);
  order_.assign(n, 0);
  mask_.assign(n, 0);
  rank_entries_.assign(n, RankEntry{0.0, 0});
  rank_scratch_.assign(n, RankEntry{0.0, 0});
  digit_counts_.assign(kDigitBuckets, 0);
  capacity_ = static_cast<int>(n);
}

}  // namespace rankslam::robust
