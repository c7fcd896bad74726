#include "status_line.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>

namespace rankslam::app {

double resident_mb() {
  const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return 0.0;
  char text[128];
  const ssize_t n = ::read(fd, text, sizeof text - 1);
  ::close(fd);
  if (n <= 0) return 0.0;
  text[n] = '\0';
  // "size resident shared ...", in pages.
  char* end = nullptr;
  (void)std::strtoull(text, &end, 10);
  const unsigned long long pages = std::strtoull(end, nullptr, 10);
  const long page_size = ::sysconf(_SC_PAGESIZE);
  return static_cast<double>(pages) * static_cast<double>(page_size > 0 ? page_size : 4096) / (1024.0 * 1024.0);
}

StatusLine::StatusLine(std::int64_t interval_ns, int fd) : interval_ns_(interval_ns), fd_(fd) {}

void StatusLine::start(std::int64_t now_ns, const StatusTotals& totals) {
  last_ns_ = now_ns;
  last_ = totals;
}

bool StatusLine::tick(std::int64_t now_ns, const StatusTotals& totals) {
  if (interval_ns_ <= 0 || now_ns - last_ns_ < interval_ns_) return false;
  const double seconds = static_cast<double>(now_ns - last_ns_) * 1e-9;
  const int tracking = totals.counts.tracking - last_.counts.tracking;
  const int degraded = totals.counts.degraded - last_.counts.degraded;
  const int lost = totals.counts.lost - last_.counts.lost;
  int written = std::snprintf(
      line_, sizeof line_,
      "status: last %.0f s: %.1f frames/s, TRACKING %d, DEGRADED %d, LOST %d, camera reads without a frame %llu; "
      "key-frames %d, RSS %.0f MB",
      seconds, static_cast<double>(tracking + degraded + lost) / seconds, tracking, degraded, lost,
      static_cast<unsigned long long>(totals.empty_reads - last_.empty_reads), totals.keyframes, resident_mb());
  if (totals.checkpoints && written > 0 && static_cast<std::size_t>(written) < sizeof line_) {
    // A disk that fills or fails shows in the journal while the run goes on, not only at exit.
    const int more = std::snprintf(
        line_ + written, sizeof line_ - static_cast<std::size_t>(written), ", checkpoints written %llu, failed %llu",
        static_cast<unsigned long long>(totals.checkpoints_written - last_.checkpoints_written),
        static_cast<unsigned long long>(totals.checkpoints_failed - last_.checkpoints_failed));
    if (more > 0) written += more;
  }
  if (totals.wide && written > 0 && static_cast<std::size_t>(written) < sizeof line_) {
    const int more = std::snprintf(
        line_ + written, sizeof line_ - static_cast<std::size_t>(written), ", wide-angle images %llu, paired %llu",
        static_cast<unsigned long long>(totals.wide_images - last_.wide_images),
        static_cast<unsigned long long>(totals.wide_paired - last_.wide_paired));
    if (more > 0) written += more;
  }
  length_ = written < 0 ? 0 : std::min(static_cast<std::size_t>(written), sizeof line_ - 2);
  line_[length_] = '\n';
  // One write per line, so lines from other threads do not interleave with it; a short or failed
  // write of the journal's stream is not worth stopping the loop for.
  (void)!::write(fd_, line_, length_ + 1);
  line_[length_] = '\0';
  last_ns_ = now_ns;
  last_ = totals;
  ++lines_;
  return true;
}

}  // namespace rankslam::app
