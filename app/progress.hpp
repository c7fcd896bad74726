#pragma once

#include <unistd.h>

#include <chrono>
#include <cstdio>

namespace rankslam::app {

/// A one-line progress display (frames/s and ETA) for long runs, drawn only when stdout is a
/// terminal so logs and pipes stay clean.
class ProgressLine {
 public:
  explicit ProgressLine(unsigned total) : total_(total), enabled_(::isatty(STDOUT_FILENO) == 1) {}

  void update(unsigned done) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_draw_ < std::chrono::milliseconds(250) && done < total_) return;
    last_draw_ = now;
    const double elapsed_s = std::chrono::duration<double>(now - start_).count();
    const double rate = elapsed_s > 0.0 ? done / elapsed_s : 0.0;
    const double eta_s = rate > 0.0 ? (total_ - done) / rate : 0.0;
    std::printf("\r  frame %u/%u  %.1f frames/s  ETA %.0f s   ", done, total_, rate, eta_s);
    std::fflush(stdout);
  }
  void finish() {
    if (enabled_) std::printf("\r%60s\r", "");
  }

 private:
  unsigned total_;
  bool enabled_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  std::chrono::steady_clock::time_point last_draw_{};
};

}  // namespace rankslam::app
