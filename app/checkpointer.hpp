#pragma once

#include "frame_pipeline.hpp"
#include "output_frame.hpp"

#include "rankslam/eval/trajectory.hpp"
#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/slam/map_builder.hpp"
#include "rankslam/slam/map_file.hpp"

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace rankslam::app {

/// What a checkpoint hands its writer: copies of the map and of the trajectory at one frame.
struct CheckpointContents {
  const slam::MapSnapshot& map;
  const eval::Trajectory& trajectory;
  std::uint64_t frames = 0;
};

/// Checkpoints of a run (`map.checkpoint_s`): every interval the loop's thread copies the map
/// and the trajectory into buffers sized at set-up, and a writer thread at low priority writes
/// them, so the loop never waits for a disk. A checkpoint falls due while the previous one is
/// still being written is left out and counted.
class Checkpointer {
 public:
  /// Writes one checkpoint; empty on success, else a message naming what was not written.
  using Writer = std::function<std::string(const CheckpointContents&)>;

  struct Counters {
    std::uint64_t written = 0;
    std::uint64_t failed = 0;
    /// Due while the writer was still busy with the previous one.
    std::uint64_t skipped = 0;
    double last_write_ms = 0.0;
    std::string last_error;
  };
  /// The counts alone: read without allocating, from the loop's thread.
  struct Tally {
    std::uint64_t written = 0;
    std::uint64_t failed = 0;
  };

  /// Set-up (allocates the copies; starts the writer). `max_poses`: the pipeline's trajectory
  /// capacity.
  Checkpointer(const slam::SlamLoop& loop, std::size_t max_poses, double interval_s, Writer write);
  ~Checkpointer();
  Checkpointer(const Checkpointer&) = delete;
  Checkpointer& operator=(const Checkpointer&) = delete;

  /// The loop's thread, every turn: when the interval has passed since the last checkpoint
  /// began, copies the pipeline's map and trajectory for the writer (no allocation). True when a
  /// checkpoint was handed over.
  bool offer(const FramePipeline& pipeline);
  /// Waits for the write under way, if any, and ends the writer; offer() then does nothing.
  void stop();
  [[nodiscard]] Counters counters() const;
  [[nodiscard]] Tally tally() const;

 private:
  void write_loop();

  std::unique_ptr<slam::MapSnapshot> map_;
  eval::Trajectory trajectory_;
  std::uint64_t frames_ = 0;
  std::chrono::steady_clock::duration interval_;
  std::chrono::steady_clock::time_point next_due_;
  Writer write_;

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  bool pending_ = false;  ///< copies handed over, not yet written
  bool stopping_ = false;
  Counters counters_;
  std::thread writer_;
};

/// What `run` writes at a checkpoint, on the checkpointer's thread: the map file (when one is
/// named) and the outputs so far, published as one set in the output directory (hal::FileSet):
/// trajectory.txt, map.ply rebuilt from the copied key-frames as at exit, and a report.json
/// marked "checkpoint". The exit's own set replaces it.
class CheckpointWriter {
 public:
  /// Set-up (allocates the point map the key-frames are rebuilt into). `config` must outlive it.
  CheckpointWriter(const slam::SlamConfig& config, const hal::Calibration& calibration, std::filesystem::path map_file,
                   std::filesystem::path out_dir, OutputFrame frame, const Eigen::Isometry3d& T_base_cam,
                   std::string software_version);
  /// Empty on success, else what was not written.
  std::string operator()(const CheckpointContents& contents);

 private:
  camera::DepthCameraModel camera_;
  slam::MapBuilder map_builder_;
  std::filesystem::path map_file_;
  std::filesystem::path out_dir_;
  OutputFrame frame_;
  Eigen::Isometry3d T_base_cam_;
  std::string software_version_;
  /// The map file's bytes: grows with the map, kept between checkpoints.
  std::vector<unsigned char> bytes_;
  /// The map file this writer last wrote: a checkpoint with the same bytes while that file is
  /// still in place leaves it alone (a robot standing still would otherwise rewrite the whole map,
  /// up to a hundred MiB, every interval onto its flash).
  struct WrittenMap {
    std::uint64_t hash = 0;
    std::uint64_t size = 0;
    std::uint64_t device = 0;
    std::uint64_t inode = 0;
  };
  std::optional<WrittenMap> written_map_;
};

}  // namespace rankslam::app
