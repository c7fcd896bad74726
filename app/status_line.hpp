#pragma once

#include "rankslam/eval/run_report.hpp"

#include <cstdint>
#include <string_view>

namespace rankslam::app {

/// What one status line reports, as totals since the start; the line shows the change since
/// the previous line.
struct StatusTotals {
  eval::StatusCounts counts;       ///< Frames by status (TRACKING, DEGRADED, LOST).
  std::uint64_t empty_reads = 0;   ///< Camera reads that brought no frame (timeout, fault).
  int keyframes = 0;
  bool checkpoints = false;              ///< Checkpoints are on: the line shows theirs.
  std::uint64_t checkpoints_written = 0;
  std::uint64_t checkpoints_failed = 0;
  bool wide = false;                     ///< A wide-angle camera is on: the line shows its images.
  std::uint64_t wide_images = 0;         ///< Its images read.
  std::uint64_t wide_paired = 0;         ///< Of those, paired with a frame.
};

/// The journal's view of `rankslam run`: every `interval_ns` one line on `fd` (stderr) with the
/// frame rate, the frames by status and the camera reads without a frame over the interval,
/// the key-frames and the resident memory, with checkpoints those written and failed, and with a
/// wide-angle camera its images read and paired with frames.
/// Called from the SLAM loop's thread (never from the pose output's real-time one); formats into
/// a fixed buffer and writes with write(2): no allocation, and a turn without a line is one
/// compare.
class StatusLine {
 public:
  /// `interval_ns` <= 0: no lines.
  StatusLine(std::int64_t interval_ns, int fd);

  /// Starts the first interval at `now_ns` (CLOCK_MONOTONIC).
  void start(std::int64_t now_ns, const StatusTotals& totals);
  /// Writes a line when an interval has passed since the previous one; true when it did.
  bool tick(std::int64_t now_ns, const StatusTotals& totals);

  /// The last line written, without its newline (empty before the first).
  [[nodiscard]] std::string_view last_line() const { return {line_, length_}; }
  [[nodiscard]] std::uint64_t lines() const { return lines_; }

 private:
  std::int64_t interval_ns_;
  int fd_;
  std::int64_t last_ns_ = 0;
  StatusTotals last_;
  char line_[256] = {};
  std::size_t length_ = 0;
  std::uint64_t lines_ = 0;
};

/// The process' resident set size now, MB (/proc/self/statm, read into a stack buffer; 0 where
/// unavailable).
[[nodiscard]] double resident_mb();

}  // namespace rankslam::app
