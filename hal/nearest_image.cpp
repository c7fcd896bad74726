#include "rankslam/hal/nearest_image.hpp"

#include <cstdlib>
#include <initializer_list>
#include <utility>

namespace rankslam::hal {

void NearestImage::allocate(int width, int height, int type) {
  behind_.frame.image.create(height, width, type);
  ahead_.frame.image.create(height, width, type);
}

const ImageFrame* NearestImage::take(std::int64_t stamp_ns, std::chrono::milliseconds wait) {
  while (!ended_ && (!ahead_.valid || ahead_.frame.stamp_ns <= stamp_ns)) {
    const ReadStatus status = camera_.read(incoming_, wait);
    last_status_ = status;
    if (status == ReadStatus::kEndOfStream) ended_ = true;
    if (status != ReadStatus::kOk) {
      if (status == ReadStatus::kFault) ++counters_.faults;
      break;
    }
    ++counters_.read;
    if (behind_.valid && !behind_.taken) ++counters_.unpaired;
    std::swap(behind_, ahead_);
    // Same size and type as the buffer: copyTo reuses it.
    incoming_.image.copyTo(ahead_.frame.image);
    ahead_.frame.sequence = incoming_.sequence;
    ahead_.frame.stamp_ns = incoming_.stamp_ns;
    ahead_.frame.stamp_s = incoming_.stamp_s;
    ahead_.valid = true;
    ahead_.taken = false;
  }
  Held* best = nullptr;
  std::int64_t best_gap = 0;
  for (Held* held : {&behind_, &ahead_}) {
    if (!held->valid || held->taken) continue;
    const std::int64_t gap = std::llabs(held->frame.stamp_ns - stamp_ns);
    // A tie goes to the earlier image.
    if (best == nullptr ? gap <= max_gap_ns_ : gap < best_gap) {
      best = held;
      best_gap = gap;
    }
  }
  if (best == nullptr) return nullptr;
  best->taken = true;
  ++counters_.paired;
  return &best->frame;
}

}  // namespace rankslam::hal
