#include "rankslam/replay/replay_stream.hpp"

#include <algorithm>
#include <cmath>
#include <exception>

namespace rankslam::replay {

ReplayStream::~ReplayStream() { stop(); }

std::string ReplayStream::start(std::uint32_t frame_count) {
  stop();
  if (!(options_.rate == 0.0 || (options_.rate >= kMinReplayRate && options_.rate <= kMaxReplayRate))) {
    return "replay rate must be 0 (as fast as possible) or between " + std::to_string(kMinReplayRate) + " and " +
           std::to_string(kMaxReplayRate);
  }
  frame_count_ = frame_count;
  {
    std::lock_guard lock(mutex_);
    slot_free_.fill(true);
    ready_head_ = ready_count_ = 0;
    held_slot_ = kPoolSlots;
    reader_done_ = false;
    stop_ = false;
    counters_ = {};
    warnings_.clear();
  }
  reader_ = std::thread([this] { reader_loop(); });
  return {};
}

void ReplayStream::stop() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  if (reader_.joinable()) reader_.join();
}

ReplayCounters ReplayStream::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

std::vector<std::string> ReplayStream::take_warnings() {
  std::lock_guard lock(mutex_);
  std::vector<std::string> taken;
  taken.swap(warnings_);
  return taken;
}

void ReplayStream::warn(std::string warning) {
  std::lock_guard lock(mutex_);
  warnings_.push_back(std::move(warning));
}

void ReplayStream::reader_loop() {
  std::uint32_t index = 0;
  // Nothing may escape the thread (std::terminate would end the process): what the per-frame
  // handling cannot absorb ends the replay here, the frames not read counted as skipped.
  try {
    read_frames(index);
  } catch (...) {
    std::lock_guard lock(mutex_);
    counters_.corrupt += frame_count_ - std::min(index, frame_count_);
    try {
      warnings_.push_back("replay reader failed at frame " + std::to_string(index) + "; the " +
                          std::to_string(frame_count_ - std::min(index, frame_count_)) +
                          " frames from there on are skipped");
    } catch (...) {
      // Out of memory for the warning as well: the count above still tells.
    }
  }
  std::lock_guard lock(mutex_);
  reader_done_ = true;
  changed_.notify_all();
}

void ReplayStream::read_frames(std::uint32_t& index) {
  const auto start = std::chrono::steady_clock::now();
  const double first_stamp_s = frame_count_ > 0 ? stamp_s(0) : 0.0;
  for (; index < frame_count_; ++index) {
    std::size_t slot_index = kPoolSlots;
    {
      std::unique_lock lock(mutex_);
      if (options_.rate <= 0.0) {
        changed_.wait(lock, [&] {
          if (stop_) return true;
          // Without decoding ahead, only while the consumer waits in next() with nothing ready.
          if (!options_.decode_ahead && (held_slot_ != kPoolSlots || ready_count_ > 0)) return false;
          return std::find(slot_free_.begin(), slot_free_.end(), true) != slot_free_.end();
        });
      }
      if (stop_) break;
      for (std::size_t i = 0; i < kPoolSlots && slot_index == kPoolSlots; ++i) {
        if (slot_free_[i]) slot_index = i;
      }
      if (slot_index == kPoolSlots) {
        // Paced replay with a slow consumer: overwrite the oldest undelivered frame.
        slot_index = ready_[ready_head_];
        ready_head_ = (ready_head_ + 1) % kPoolSlots;
        --ready_count_;
        ++counters_.dropped;
      }
      slot_free_[slot_index] = false;
    }
    std::string error;
    try {
      error = decode_into(index, slot_index);
    } catch (const std::exception& exception) {
      error = describe(index) + ": cannot be read (" + exception.what() + "), skipped";
    }
    if (options_.rate > 0.0) {
      // Capped so that a huge stamp gap (or a tiny rate) cannot overflow the clock's ticks.
      constexpr double kMaxPacingWait_s = 365.0 * 24.0 * 3600.0;
      const double offset_s = std::min((stamp_s(index) - first_stamp_s) / options_.rate, kMaxPacingWait_s);
      const auto due = start + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                   std::chrono::duration<double>(offset_s));
      std::unique_lock lock(mutex_);
      changed_.wait_until(lock, due, [&] { return stop_; });
    }
    std::lock_guard lock(mutex_);
    if (!error.empty()) {
      ++counters_.corrupt;
      slot_free_[slot_index] = true;
      warnings_.push_back(error);
      continue;
    }
    ready_[(ready_head_ + ready_count_) % kPoolSlots] = slot_index;
    ++ready_count_;
    changed_.notify_all();
  }
}

hal::ReadStatus ReplayStream::next(std::size_t& slot, std::chrono::milliseconds wait) {
  std::unique_lock lock(mutex_);
  if (held_slot_ != kPoolSlots) {
    slot_free_[held_slot_] = true;
    held_slot_ = kPoolSlots;
    changed_.notify_all();
  }
  if (!changed_.wait_for(lock, wait, [&] { return ready_count_ > 0 || reader_done_ || stop_; })) {
    return hal::ReadStatus::kTimeout;
  }
  if (ready_count_ == 0) return hal::ReadStatus::kEndOfStream;
  held_slot_ = ready_[ready_head_];
  ready_head_ = (ready_head_ + 1) % kPoolSlots;
  --ready_count_;
  slot = held_slot_;
  ++counters_.delivered;
  return hal::ReadStatus::kOk;
}

}  // namespace rankslam::replay
