#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"

#include <opencv2/core/mat.hpp>

#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace rankslam::record {

/// Set-up of a RecordingWriter; fixed after construction.
struct RecordingWriterOptions {
  /// RGB-D frames waiting for the writer at most; when all are taken, new frames are dropped
  /// (and counted) rather than stalling capture.
  std::size_t frame_queue = 16;
  /// CAN frames waiting for the writer at most.
  std::size_t can_queue = 8192;
  /// Write ir/ and ir.txt for frames that carry an IR image.
  bool write_ir = true;
  /// Wide-angle images waiting for the writer at most (push_wide).
  std::size_t wide_queue = 8;
  /// Write can.log (frames given to push_can) naming this interface, as candump -l does.
  bool write_can = false;
  std::string can_interface = "can0";
  /// PNG compression level 0..9: 1 keeps up with 30 Hz VGA on one core.
  int png_compression = 1;
};

/// Counters since open().
struct RecordingCounters {
  std::uint64_t frames_queued = 0;   ///< RGB-D frames accepted by push().
  std::uint64_t frames_written = 0;  ///< RGB-D frames on disk and in the index files.
  std::uint64_t frames_dropped = 0;  ///< Frames refused because the queue was full.
  std::uint64_t frames_failed = 0;   ///< Frames that could not be encoded or written.
  std::uint64_t ir_written = 0;      ///< IR images written.
  std::uint64_t wide_written = 0;    ///< Wide-angle images on disk and in fisheye.txt.
  std::uint64_t wide_dropped = 0;    ///< Wide-angle images refused: queue full, wrong size, no calibration.
  std::uint64_t wide_failed = 0;     ///< Wide-angle images that could not be encoded or written.
  std::uint64_t can_written = 0;     ///< CAN frames in can.log.
  std::uint64_t can_dropped = 0;     ///< CAN frames refused because the queue was full.
};

/// Writes a recording directory: rgb/ and depth/ PNGs, rgb.txt, depth.txt, associations.txt,
/// optional ir/ + ir.txt, fisheye/ + fisheye.txt and can.log, and calibration.yaml. push() copies a frame into one of
/// the slots allocated at open() and returns at once; a writer thread encodes the PNGs and
/// appends the index lines only after the images are completely on disk, and flushes them, so
/// a recording stopped at any moment (a signal, a crash) is a valid recording of the frames
/// listed.
class RecordingWriter {
 public:
  RecordingWriter(std::filesystem::path root, RecordingWriterOptions options);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  /// Creates the directory (absent or empty), writes calibration.yaml atomically, opens the
  /// index files and starts the writer. Images must have the calibration's colour size.
  /// Empty on success, otherwise what went wrong, naming the path.
  [[nodiscard]] std::string open(const hal::Calibration& calibration);
  /// Queues a copy of `frame`; false when it was dropped (queue full, wrong size, not open).
  bool push(const hal::RgbdFrame& frame);
  /// Queues a copy of a wide-angle image for fisheye/; false when it was dropped (queue full,
  /// not of the calibration's cameras.fisheye size, no such camera, not open).
  bool push_wide(const hal::ImageFrame& image);
  /// Queues a CAN frame for can.log; false when it was dropped.
  bool push_can(const hal::CanFrame& frame);
  /// Writes everything queued, closes the files and stops the writer. Empty on success,
  /// otherwise the first write error.
  [[nodiscard]] std::string close();

  [[nodiscard]] RecordingCounters counters() const;
  [[nodiscard]] const std::filesystem::path& root() const { return root_; }

 private:
  struct Slot {
    std::uint32_t sequence = 0;
    double stamp_s = 0.0;
    cv::Mat rgb;
    cv::Mat depth;
    cv::Mat ir;
    bool has_ir = false;
    /// A wide-angle image slot: `rgb` holds the image; depth and IR are unused.
    bool wide = false;
  };

  void writer_loop();
  /// Encodes and writes one frame; empty on success.
  std::string write_frame(Slot& slot);
  /// Encodes and writes one wide-angle image; empty on success.
  std::string write_wide(Slot& slot);
  std::string write_png(const std::filesystem::path& path, const cv::Mat& image);
  void write_can_lines();

  std::filesystem::path root_;
  RecordingWriterOptions options_;
  hal::Calibration calibration_;

  std::vector<Slot> slots_;
  std::vector<std::size_t> ready_;  // ring of slot indices, oldest first
  std::size_t ready_head_ = 0;
  std::size_t ready_count_ = 0;
  std::vector<std::size_t> free_;   // stack of free RGB-D slot indices
  std::vector<std::size_t> wide_free_;  // stack of free wide-angle slot indices (after the RGB-D ones)
  std::vector<hal::CanFrame> can_ring_;
  std::size_t can_head_ = 0;
  std::size_t can_count_ = 0;
  std::vector<hal::CanFrame> can_batch_;  // writer-side copy, reserved at open()

  mutable std::mutex mutex_;
  std::condition_variable changed_;
  bool stop_ = false;
  bool open_ = false;
  RecordingCounters counters_;
  std::string first_error_;
  std::thread writer_;

  // Writer-thread state.
  std::vector<unsigned char> png_buffer_;
  std::vector<int> png_parameters_;
  std::FILE* rgb_index_ = nullptr;
  std::FILE* depth_index_ = nullptr;
  std::FILE* associations_ = nullptr;
  std::FILE* ir_index_ = nullptr;
  std::FILE* wide_index_ = nullptr;
  std::FILE* can_log_ = nullptr;
};

/// calibration.yaml text for `calibration`, in the format load_calibration_yaml reads.
[[nodiscard]] std::string calibration_yaml(const hal::Calibration& calibration, const std::string& comment);

}  // namespace rankslam::record
