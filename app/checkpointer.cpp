#include "checkpointer.hpp"

#include "rankslam/eval/run_report.hpp"
#include "rankslam/hal/file_set.hpp"

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <span>

namespace rankslam::app {
namespace {

/// FNV-1a over the bytes: tells one map encoding from another (not a defence against forgery).
std::uint64_t fnv1a(std::span<const unsigned char> bytes) {
  std::uint64_t hash = 14695981039346656037ULL;
  for (const unsigned char byte : bytes) {
    hash ^= byte;
    hash *= 1099511628211ULL;
  }
  return hash;
}

}  // namespace

Checkpointer::Checkpointer(const slam::SlamLoop& loop, std::size_t max_poses, double interval_s, Writer write)
    : map_(loop.make_map_snapshot()),
      interval_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(interval_s))),
      next_due_(std::chrono::steady_clock::now() + interval_),
      write_(std::move(write)) {
  trajectory_.reserve(max_poses);
  writer_ = std::thread([this] { write_loop(); });
}

Checkpointer::~Checkpointer() { stop(); }

bool Checkpointer::offer(const FramePipeline& pipeline) {
  const auto now = std::chrono::steady_clock::now();
  if (now < next_due_) return false;
  std::unique_lock lock(mutex_);
  if (stopping_) return false;
  next_due_ = now + interval_;
  if (pending_) {
    ++counters_.skipped;
    return false;
  }
  lock.unlock();
  // The writer is idle and does not touch the copies until pending_ is set.
  pipeline.loop().snapshot_map(*map_);
  const eval::Trajectory& trajectory = pipeline.trajectory();
  trajectory_.assign(trajectory.begin(), trajectory.begin() + static_cast<std::ptrdiff_t>(std::min(trajectory.size(), trajectory_.capacity())));
  frames_ = pipeline.frames();
  lock.lock();
  pending_ = true;
  lock.unlock();
  wake_.notify_one();
  return true;
}

void Checkpointer::stop() {
  {
    const std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  if (writer_.joinable()) writer_.join();
}

Checkpointer::Counters Checkpointer::counters() const {
  const std::lock_guard lock(mutex_);
  return counters_;
}

Checkpointer::Tally Checkpointer::tally() const {
  const std::lock_guard lock(mutex_);
  return {counters_.written, counters_.failed};
}

void Checkpointer::write_loop() {
  // Below the loop's priority: a checkpoint takes what the SLAM leaves of the CPU.
  (void)::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return pending_ || stopping_; });
    if (!pending_) return;  // stopping with nothing to write
    lock.unlock();
    const auto start = std::chrono::steady_clock::now();
    const std::string error = write_({*map_, trajectory_, frames_});
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    lock.lock();
    pending_ = false;
    counters_.last_write_ms = ms;
    if (error.empty()) {
      ++counters_.written;
    } else {
      ++counters_.failed;
      counters_.last_error = error;
    }
  }
}

CheckpointWriter::CheckpointWriter(const slam::SlamConfig& config, const hal::Calibration& calibration,
                                   std::filesystem::path map_file, std::filesystem::path out_dir, OutputFrame frame,
                                   const Eigen::Isometry3d& T_base_cam, std::string software_version)
    : camera_(calibration),
      map_builder_(config, camera_),
      map_file_(std::move(map_file)),
      out_dir_(std::move(out_dir)),
      frame_(frame),
      T_base_cam_(T_base_cam),
      software_version_(std::move(software_version)) {}

std::string CheckpointWriter::operator()(const CheckpointContents& contents) {
  std::string error;
  if (!map_file_.empty()) {
    slam::encode_map(contents.map.store, contents.map.graph, contents.map.threshold, contents.map.digests, bytes_);
    const std::uint64_t hash = fnv1a(bytes_);
    struct stat status {};
    // The same file as last written (not moved away or replaced) with the same bytes.
    const bool unchanged = written_map_ && written_map_->hash == hash && written_map_->size == bytes_.size() &&
                           ::stat(map_file_.c_str(), &status) == 0 && written_map_->device == status.st_dev &&
                           written_map_->inode == status.st_ino &&
                           static_cast<std::uint64_t>(status.st_size) == bytes_.size();
    if (!unchanged) {
      written_map_.reset();
      error = slam::write_map_bytes(map_file_, bytes_);
      if (error.empty() && ::stat(map_file_.c_str(), &status) == 0) {
        written_map_ = WrittenMap{hash, bytes_.size(), static_cast<std::uint64_t>(status.st_dev),
                                  static_cast<std::uint64_t>(status.st_ino)};
      }
    }
  }
  map_builder_.rebuild_copy(contents.map.store);
  hal::FileSet set(out_dir_);
  std::string set_error = set.add_written("trajectory.txt", [&](const std::filesystem::path& path) {
    return eval::write_tum_trajectory(path, in_output_frame(contents.trajectory, frame_, T_base_cam_));
  });
  if (set_error.empty()) {
    set_error = set.add("map.ply", std::string_view(map_builder_.map().to_ply(output_from_world(frame_, T_base_cam_))));
  }
  if (set_error.empty()) {
    eval::JsonWriter json;
    json.begin_object();
    eval::write_report_header(json, software_version_, "run");
    json.boolean("checkpoint", true);
    json.string("output_frame", to_string(frame_));
    json.integer("frames", static_cast<long long>(contents.frames));
    json.integer("keyframes", contents.map.store.size());
    json.string("map_file", map_file_.string());
    json.end_object();
    set_error = set.add("report.json", std::string_view(json.str()));
  }
  if (set_error.empty()) set_error = set.publish();
  if (!set_error.empty()) error += (error.empty() ? "" : "; ") + set_error;
  return error;
}

}  // namespace rankslam::app
