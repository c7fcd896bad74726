#include "rankslam/record/recording_writer.hpp"

#include "rankslam/hal/atomic_file.hpp"
#include "rankslam/hal/candump.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace rankslam::record {
namespace {

namespace fs = std::filesystem;

std::string errno_text() { return std::strerror(errno); }

}  // namespace

RecordingWriter::RecordingWriter(fs::path root, RecordingWriterOptions options)
    : root_(std::move(root)), options_(std::move(options)) {}

RecordingWriter::~RecordingWriter() { (void)close(); }

std::string RecordingWriter::open(const hal::Calibration& calibration) {
  (void)close();
  if (options_.frame_queue < 1 || options_.frame_queue > 1024) return "recording: frame_queue must be 1..1024";
  if (options_.wide_queue > 1024) return "recording: wide_queue must be 0..1024";
  if (options_.png_compression < 0 || options_.png_compression > 9) return "recording: png_compression must be 0..9";
  std::error_code ec;
  if (fs::exists(root_, ec)) {
    if (!fs::is_directory(root_, ec)) return root_.string() + ": exists and is not a directory";
    if (!fs::is_empty(root_, ec)) return root_.string() + ": not empty; record into a new directory";
  }
  const bool wide = calibration.fisheye.has_value() && options_.wide_queue > 0;
  for (const char* sub : {"rgb", "depth", "ir", "fisheye"}) {
    if (std::string(sub) == "ir" && !options_.write_ir) continue;
    if (std::string(sub) == "fisheye" && !wide) continue;
    fs::create_directories(root_ / sub, ec);
    if (ec) return (root_ / sub).string() + ": cannot create: " + ec.message();
  }
  calibration_ = calibration;
  if (auto error = hal::write_file_atomically(root_ / "calibration.yaml",
                                              std::string_view(calibration_yaml(calibration, "rankslam record")));
      !error.empty()) {
    return error;
  }
  const auto open_index = [&](const char* name, const char* header, std::FILE*& file) -> std::string {
    const fs::path path = root_ / name;
    file = std::fopen(path.c_str(), "w");
    if (file == nullptr) return path.string() + ": cannot create: " + errno_text();
    if (std::fputs(header, file) < 0 || std::fflush(file) != 0) return path.string() + ": cannot write: " + errno_text();
    return {};
  };
  std::string error;
  const auto check = [&](std::string e) {
    if (error.empty()) error = std::move(e);
  };
  check(open_index("rgb.txt", "# colour images\n# file: 'rankslam record'\n# timestamp filename\n", rgb_index_));
  check(open_index("depth.txt", "# depth maps\n# file: 'rankslam record'\n# timestamp filename\n", depth_index_));
  check(open_index("associations.txt", "# rgb_timestamp rgb_file depth_timestamp depth_file\n", associations_));
  if (options_.write_ir) check(open_index("ir.txt", "# infrared images\n# file: 'rankslam record'\n# timestamp filename\n", ir_index_));
  if (wide) check(open_index("fisheye.txt", "# wide-angle images\n# file: 'rankslam record'\n# timestamp filename\n", wide_index_));
  if (options_.write_can) check(open_index("can.log", "", can_log_));
  if (!error.empty()) {
    (void)close();
    return error;
  }

  // Every buffer the capture side touches is allocated here.
  const int width = calibration.rgb.width;
  const int height = calibration.rgb.height;
  const std::size_t wide_slots = wide ? options_.wide_queue : 0;
  slots_.assign(options_.frame_queue + wide_slots, Slot{});
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    Slot& slot = slots_[i];
    slot.wide = i >= options_.frame_queue;
    if (slot.wide) {
      slot.rgb.create(calibration.fisheye->height, calibration.fisheye->width, CV_8UC3);
    } else {
      slot.rgb.create(height, width, CV_8UC3);
      slot.depth.create(height, width, CV_16UC1);
    }
  }
  ready_.assign(slots_.size(), 0);
  free_.clear();
  free_.reserve(options_.frame_queue);
  for (std::size_t i = options_.frame_queue; i-- > 0;) free_.push_back(i);
  wide_free_.clear();
  wide_free_.reserve(wide_slots);
  for (std::size_t i = slots_.size(); i-- > options_.frame_queue;) wide_free_.push_back(i);
  ready_head_ = ready_count_ = 0;
  can_ring_.assign(options_.write_can ? std::max<std::size_t>(options_.can_queue, 1) : 1, hal::CanFrame{});
  can_batch_.clear();
  can_batch_.reserve(can_ring_.size());
  can_head_ = can_count_ = 0;
  png_buffer_.reserve(static_cast<std::size_t>(width) * height * 3);
  png_parameters_ = {cv::IMWRITE_PNG_COMPRESSION, options_.png_compression};
  counters_ = {};
  first_error_.clear();
  stop_ = false;
  open_ = true;
  writer_ = std::thread([this] { writer_loop(); });
  return {};
}

bool RecordingWriter::push(const hal::RgbdFrame& frame) {
  std::size_t index = 0;
  {
    std::lock_guard lock(mutex_);
    if (!open_ || stop_ || free_.empty() || frame.rgb.size() != slots_.front().rgb.size() ||
        frame.rgb.type() != CV_8UC3 || frame.depth.size() != frame.rgb.size() || frame.depth.type() != CV_16UC1) {
      ++counters_.frames_dropped;
      return false;
    }
    index = free_.back();
    free_.pop_back();
  }
  // The slot is ours alone until queued: copy outside the lock (same size and type: no allocation).
  Slot& slot = slots_[index];
  slot.sequence = frame.sequence;
  slot.stamp_s = frame.stamp_s;
  frame.rgb.copyTo(slot.rgb);
  frame.depth.copyTo(slot.depth);
  slot.has_ir = options_.write_ir && !frame.ir.empty() && frame.ir.size() == frame.rgb.size();
  // IR arrives in one format per device; the first frame fixes the slot's buffer.
  if (slot.has_ir) frame.ir.copyTo(slot.ir);
  {
    std::lock_guard lock(mutex_);
    ready_[(ready_head_ + ready_count_) % ready_.size()] = index;
    ++ready_count_;
    ++counters_.frames_queued;
  }
  changed_.notify_one();
  return true;
}

bool RecordingWriter::push_wide(const hal::ImageFrame& image) {
  std::size_t index = 0;
  {
    std::lock_guard lock(mutex_);
    if (!open_ || stop_ || wide_free_.empty() || image.image.size() != slots_[wide_free_.back()].rgb.size() ||
        (image.image.type() != CV_8UC3 && image.image.type() != CV_8UC1)) {
      ++counters_.wide_dropped;
      return false;
    }
    index = wide_free_.back();
    wide_free_.pop_back();
  }
  Slot& slot = slots_[index];
  slot.sequence = image.sequence;
  slot.stamp_s = image.stamp_s;
  // A camera streams one type: a grey one reallocates each slot once, at its first image.
  image.image.copyTo(slot.rgb);
  {
    std::lock_guard lock(mutex_);
    ready_[(ready_head_ + ready_count_) % ready_.size()] = index;
    ++ready_count_;
  }
  changed_.notify_one();
  return true;
}

bool RecordingWriter::push_can(const hal::CanFrame& frame) {
  {
    std::lock_guard lock(mutex_);
    if (!open_ || stop_ || !options_.write_can || can_count_ == can_ring_.size()) {
      ++counters_.can_dropped;
      return false;
    }
    can_ring_[(can_head_ + can_count_) % can_ring_.size()] = frame;
    ++can_count_;
  }
  changed_.notify_one();
  return true;
}

std::string RecordingWriter::write_png(const fs::path& path, const cv::Mat& image) {
  try {
    if (!cv::imencode(".png", image, png_buffer_, png_parameters_)) return path.string() + ": PNG encoding failed";
  } catch (const cv::Exception& error) {
    return path.string() + ": PNG encoding failed: " + error.what();
  }
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) return path.string() + ": cannot create: " + errno_text();
  const bool ok = std::fwrite(png_buffer_.data(), 1, png_buffer_.size(), file) == png_buffer_.size();
  const bool closed = std::fclose(file) == 0;
  if (!ok || !closed) return path.string() + ": cannot write: " + errno_text();
  return {};
}

std::string RecordingWriter::write_frame(Slot& slot) {
  char name[64];
  std::snprintf(name, sizeof name, "%.6f.png", slot.stamp_s);
  const std::string rgb_file = std::string("rgb/") + name;
  const std::string depth_file = std::string("depth/") + name;
  if (auto error = write_png(root_ / rgb_file, slot.rgb); !error.empty()) return error;
  if (auto error = write_png(root_ / depth_file, slot.depth); !error.empty()) return error;
  const bool ir = slot.has_ir && ir_index_ != nullptr;
  const std::string ir_file = std::string("ir/") + name;
  if (ir) {
    if (auto error = write_png(root_ / ir_file, slot.ir); !error.empty()) return error;
  }
  // Index lines only for images completely on disk, flushed at once: the recording is valid
  // whenever it stops.
  char stamp[32];
  std::snprintf(stamp, sizeof stamp, "%.6f", slot.stamp_s);
  bool ok = std::fprintf(rgb_index_, "%s %s\n", stamp, rgb_file.c_str()) > 0 &&
            std::fprintf(depth_index_, "%s %s\n", stamp, depth_file.c_str()) > 0 &&
            std::fprintf(associations_, "%s %s %s %s\n", stamp, rgb_file.c_str(), stamp, depth_file.c_str()) > 0;
  if (ir) ok = ok && std::fprintf(ir_index_, "%s %s\n", stamp, ir_file.c_str()) > 0;
  for (std::FILE* file : {rgb_index_, depth_index_, associations_, ir ? ir_index_ : nullptr}) {
    if (file != nullptr && std::fflush(file) != 0) ok = false;
  }
  if (!ok) return (root_ / "rgb.txt").string() + " (and the other index files): cannot write: " + errno_text();
  std::lock_guard lock(mutex_);
  if (ir) ++counters_.ir_written;
  return {};
}

std::string RecordingWriter::write_wide(Slot& slot) {
  char name[64];
  std::snprintf(name, sizeof name, "fisheye/%.6f.png", slot.stamp_s);
  if (auto error = write_png(root_ / name, slot.rgb); !error.empty()) return error;
  if (std::fprintf(wide_index_, "%.6f %s\n", slot.stamp_s, name) <= 0 || std::fflush(wide_index_) != 0) {
    return (root_ / "fisheye.txt").string() + ": cannot write: " + errno_text();
  }
  return {};
}

void RecordingWriter::write_can_lines() {
  if (can_log_ == nullptr || can_batch_.empty()) return;
  bool ok = true;
  for (const hal::CanFrame& frame : can_batch_) {
    const std::string line = hal::format_candump_line(frame, options_.can_interface);
    ok = ok && std::fprintf(can_log_, "%s\n", line.c_str()) > 0;
  }
  ok = ok && std::fflush(can_log_) == 0;
  std::lock_guard lock(mutex_);
  if (ok) {
    counters_.can_written += can_batch_.size();
  } else if (first_error_.empty()) {
    first_error_ = (root_ / "can.log").string() + ": cannot write: " + errno_text();
  }
}

void RecordingWriter::writer_loop() {
  for (;;) {
    std::size_t index = slots_.size();
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return stop_ || ready_count_ > 0 || can_count_ > 0; });
      can_batch_.clear();
      while (can_count_ > 0) {
        can_batch_.push_back(can_ring_[can_head_]);
        can_head_ = (can_head_ + 1) % can_ring_.size();
        --can_count_;
      }
      if (ready_count_ > 0) {
        index = ready_[ready_head_];
        ready_head_ = (ready_head_ + 1) % ready_.size();
        --ready_count_;
      } else if (stop_ && can_batch_.empty()) {
        return;  // everything queued before close() is written
      }
    }
    write_can_lines();
    if (index == slots_.size()) continue;
    Slot& slot = slots_[index];
    const std::string error = slot.wide ? write_wide(slot) : write_frame(slot);
    std::lock_guard lock(mutex_);
    if (error.empty()) {
      ++(slot.wide ? counters_.wide_written : counters_.frames_written);
    } else {
      ++(slot.wide ? counters_.wide_failed : counters_.frames_failed);
      if (first_error_.empty()) first_error_ = error;
    }
    (slot.wide ? wide_free_ : free_).push_back(index);
  }
}

std::string RecordingWriter::close() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  if (writer_.joinable()) writer_.join();
  std::string error;
  for (std::FILE** file : {&rgb_index_, &depth_index_, &associations_, &ir_index_, &wide_index_, &can_log_}) {
    if (*file != nullptr && std::fclose(*file) != 0 && error.empty()) error = root_.string() + ": closing an index file: " + errno_text();
    *file = nullptr;
  }
  std::lock_guard lock(mutex_);
  open_ = false;
  if (!first_error_.empty()) return first_error_;
  return error;
}

RecordingCounters RecordingWriter::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

}  // namespace rankslam::record
