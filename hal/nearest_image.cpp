#include "rankslam/hal/nearest_image.hpp"

#include <cstdlib>

namespace rankslam::hal {

void NearestImage::allocate(int width, int height, int type) {
  for (Held& held : held_) held.frame.image.create(height, width, type);
  handed_.image.create(height, width, type);
}

void NearestImage::start_reader(std::chrono::milliseconds wait) {
  stop_reader();
  stop_ = false;
  reader_ = std::thread([this, wait] {
    while (!stop_.load()) {
      (void)read_one(wait);
      if (ended()) break;
    }
  });
}

void NearestImage::stop_reader() {
  stop_ = true;
  if (reader_.joinable()) reader_.join();
}

bool NearestImage::read_one(std::chrono::milliseconds wait) {
  // The read itself is outside the lock: a live camera's wait must not hold up take().
  const ReadStatus status = camera_.read(incoming_, wait);
  std::lock_guard lock(mutex_);
  last_status_ = status;
  if (status == ReadStatus::kEndOfStream) ended_ = true;
  if (status != ReadStatus::kOk) {
    if (status == ReadStatus::kFault) ++counters_.faults;
    return false;
  }
  ++counters_.read;
  newest_ = (newest_ + 1) % kHeld;
  Held& slot = held_[newest_];
  if (slot.valid && !slot.taken) ++counters_.unpaired;
  // Same size and type as the buffer: copyTo reuses it.
  incoming_.image.copyTo(slot.frame.image);
  slot.frame.sequence = incoming_.sequence;
  slot.frame.stamp_ns = incoming_.stamp_ns;
  slot.frame.stamp_s = incoming_.stamp_s;
  slot.valid = true;
  slot.taken = false;
  return true;
}

const ImageFrame* NearestImage::take(std::int64_t stamp_ns, std::chrono::milliseconds wait) {
  const bool reading_here = !reader_.joinable();
  while (reading_here && !ended_) {
    const Held& newest = held_[newest_];
    if (newest.valid && newest.frame.stamp_ns > stamp_ns) break;
    if (!read_one(wait)) break;
  }
  std::lock_guard lock(mutex_);
  Held* best = nullptr;
  std::int64_t best_gap = 0;
  // Oldest first, so that a tie goes to the earlier image.
  for (std::size_t k = 1; k <= kHeld; ++k) {
    Held& held = held_[(newest_ + k) % kHeld];
    if (!held.valid || held.taken) continue;
    const std::int64_t gap = std::llabs(held.frame.stamp_ns - stamp_ns);
    if (best == nullptr ? gap <= max_gap_ns_ : gap < best_gap) {
      best = &held;
      best_gap = gap;
    }
  }
  if (best == nullptr) return nullptr;
  best->taken = true;
  ++counters_.paired;
  if (reading_here) return &best->frame;
  best->frame.image.copyTo(handed_.image);
  handed_.sequence = best->frame.sequence;
  handed_.stamp_ns = best->frame.stamp_ns;
  handed_.stamp_s = best->frame.stamp_s;
  return &handed_;
}

bool NearestImage::ended() const {
  std::lock_guard lock(mutex_);
  return ended_;
}

ReadStatus NearestImage::last_status() const {
  std::lock_guard lock(mutex_);
  return last_status_;
}

NearestImageCounters NearestImage::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

}  // namespace rankslam::hal
