#include "rankslam/replay/replay_camera.hpp"

#include "rankslam/hal/image_header.hpp"
#include "rankslam/hal/regular_file.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <exception>
#include <initializer_list>

namespace rankslam::replay {
namespace {

// Larger is not a camera frame: 64 MiB holds an uncompressed 16-bit three-channel 4K image (50 MB).
constexpr std::size_t kMaxImageFileBytes = std::size_t{64} << 20U;

// A decoder may turn an image by its EXIF orientation, so either way round is the calibration's size.
bool has_size(const hal::ImageHeader& header, const hal::CameraCalibration& camera) {
  return (header.width == camera.width && header.height == camera.height) ||
         (header.width == camera.height && header.height == camera.width);
}

// Reads an image file into `buffer`, reusing its capacity, and checks from its header, before
// anything is decoded, that it has the calibration's size. Empty on success, else what is wrong.
std::string read_image(const std::filesystem::path& path, const hal::CameraCalibration& camera,
                       std::vector<unsigned char>& buffer, hal::ImageHeader& header) {
  if (auto error = hal::read_regular_file(path, kMaxImageFileBytes, buffer); !error.empty()) return error;
  const auto read = hal::read_image_header(buffer);
  if (!read) return path.string() + ": not a decodable image";
  header = *read;
  if (!has_size(header, camera)) {
    return path.string() + ": " + std::to_string(header.width) + "x" + std::to_string(header.height) +
           " but the calibration says " + std::to_string(camera.width) + "x" + std::to_string(camera.height);
  }
  return {};
}

// True when the buffer starts like an image format the replay accepts (PNG, JPEG, PPM/PGM,
// TIFF). OpenCV leaves a preallocated destination untouched, and reports nothing, when no
// decoder recognises the data, so unknown data must be caught before decoding.
bool has_image_signature(const std::vector<unsigned char>& buffer) {
  const auto starts_with = [&](std::initializer_list<unsigned char> prefix) {
    return buffer.size() >= prefix.size() && std::equal(prefix.begin(), prefix.end(), buffer.begin());
  };
  return starts_with({0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'}) || starts_with({0xFF, 0xD8, 0xFF}) ||
         starts_with({'P', '5'}) || starts_with({'P', '6'}) || starts_with({'I', 'I', 0x2A, 0x00}) ||
         starts_with({'M', 'M', 0x00, 0x2A});
}

// Decodes `buffer` into `image` in place when its size and type already fit. A decoder that
// fails after reading the header releases `image`, so an empty result means corrupt data.
bool decode(const std::vector<unsigned char>& buffer, int flags, cv::Mat& image) {
  if (!has_image_signature(buffer)) return false;
  try {
    cv::Mat decoded = cv::imdecode(buffer, flags, &image);
    return !decoded.empty();
  } catch (const cv::Exception&) {
    return false;
  }
}

}  // namespace

ReplayDepthCamera::ReplayDepthCamera(const Recording& recording, ReplayOptions options)
    : recording_(recording), options_(options) {}

ReplayDepthCamera::~ReplayDepthCamera() { close(); }

std::string ReplayDepthCamera::open() {
  close();
  const auto total = static_cast<std::uint32_t>(recording_.frames.size());
  frame_count_ = options_.max_frames > 0 ? std::min(options_.max_frames, total) : total;
  if (frame_count_ == 0) return recording_.root.string() + ": no frames to replay";
  if (!(options_.rate == 0.0 || (options_.rate >= kMinReplayRate && options_.rate <= kMaxReplayRate))) {
    return "replay rate must be 0 (as fast as possible) or between " + std::to_string(kMinReplayRate) + " and " +
           std::to_string(kMaxReplayRate);
  }
  const auto& camera = recording_.calibration.rgb;
  for (auto& slot : slots_) {
    // Allocate every image once so decoding reuses the memory.
    slot.frame.rgb.create(camera.height, camera.width, CV_8UC3);
    slot.frame.depth.create(camera.height, camera.width, CV_16UC1);
    slot.frame.ir.release();
    slot.file_buffer.reserve(static_cast<std::size_t>(camera.width) * camera.height * 3);
  }
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

void ReplayDepthCamera::close() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  changed_.notify_all();
  if (reader_.joinable()) reader_.join();
}

ReplayCounters ReplayDepthCamera::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

std::vector<std::string> ReplayDepthCamera::take_warnings() {
  std::lock_guard lock(mutex_);
  std::vector<std::string> taken;
  taken.swap(warnings_);
  return taken;
}

std::string ReplayDepthCamera::decode_into(std::uint32_t index, Slot& slot) {
  const FrameEntry& entry = recording_.frames[index];
  const auto& camera = recording_.calibration.rgb;
  const auto frame_name = "frame " + std::to_string(index) + " (" + entry.rgb_file + ")";
  const auto rgb_path = recording_.root / entry.rgb_file;
  const auto depth_path = recording_.root / entry.depth_file;

  hal::ImageHeader header;
  if (auto error = read_image(rgb_path, camera, slot.file_buffer, header); !error.empty()) {
    return error + ", " + frame_name + " skipped";
  }
  if (!decode(slot.file_buffer, cv::IMREAD_COLOR, slot.frame.rgb)) {
    return rgb_path.string() + ": not a decodable image, " + frame_name + " skipped";
  }
  if (slot.frame.rgb.cols != camera.width || slot.frame.rgb.rows != camera.height) {
    return rgb_path.string() + ": " + std::to_string(slot.frame.rgb.cols) + "x" + std::to_string(slot.frame.rgb.rows) +
           " but the calibration says " + std::to_string(camera.width) + "x" + std::to_string(camera.height) + ", " +
           frame_name + " skipped";
  }
  constexpr const char* kDepthLayout = "depth must be 16-bit single channel of the colour image's size, ";
  if (auto error = read_image(depth_path, camera, slot.file_buffer, header); !error.empty()) {
    return error + ", " + frame_name + " skipped";
  }
  // IMREAD_ANYDEPTH would quietly turn a colour image into grey, so the layout is checked first.
  if (header.channels != 1 || header.bit_depth != 16) {
    return depth_path.string() + ": " + std::to_string(header.channels) + " channels of " +
           std::to_string(header.bit_depth) + " bits, but " + kDepthLayout + frame_name + " skipped";
  }
  if (!decode(slot.file_buffer, cv::IMREAD_ANYDEPTH, slot.frame.depth)) {
    return depth_path.string() + ": not a decodable image, " + frame_name + " skipped";
  }
  if (slot.frame.depth.type() != CV_16UC1 || slot.frame.depth.size() != slot.frame.rgb.size()) {
    return depth_path.string() + ": " + kDepthLayout + frame_name + " skipped";
  }
  slot.frame.ir.release();
  if (options_.load_ir && !entry.ir_file.empty()) {
    const auto ir_path = recording_.root / entry.ir_file;
    // A bad IR image costs the IR stream for this frame, not the frame.
    if (!read_image(ir_path, camera, slot.file_buffer, header).empty() ||
        !decode(slot.file_buffer, cv::IMREAD_GRAYSCALE, slot.frame.ir) || slot.frame.ir.size() != slot.frame.rgb.size()) {
      slot.frame.ir.release();
      std::lock_guard lock(mutex_);
      warnings_.push_back(ir_path.string() + ": missing or undecodable IR image, " + frame_name + " has no IR");
    }
  }
  slot.frame.sequence = index;
  slot.frame.stamp_s = entry.rgb_stamp_s;
  slot.frame.stamp_ns = static_cast<std::int64_t>(std::llround(entry.rgb_stamp_s * 1e9));
  return {};
}

void ReplayDepthCamera::reader_loop() {
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

void ReplayDepthCamera::read_frames(std::uint32_t& index) {
  const auto start = std::chrono::steady_clock::now();
  const double first_stamp_s = recording_.frames.front().rgb_stamp_s;
  for (; index < frame_count_; ++index) {
    std::size_t slot_index = kPoolSlots;
    {
      std::unique_lock lock(mutex_);
      if (options_.rate <= 0.0) {
        changed_.wait(lock, [&] {
          if (stop_) return true;
          // Without decoding ahead, only while the consumer waits in read() with nothing ready.
          if (!options_.decode_ahead && (held_slot_ != kPoolSlots || ready_count_ > 0)) return false;
          for (std::size_t i = 0; i < kPoolSlots; ++i) {
            if (slot_free_[i]) return true;
          }
          return false;
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
    Slot& slot = slots_[slot_index];
    std::string error;
    try {
      error = decode_into(index, slot);
    } catch (const std::exception& exception) {
      error = "frame " + std::to_string(index) + " (" + recording_.frames[index].rgb_file +
              "): cannot be read (" + exception.what() + "), skipped";
    }
    if (options_.rate > 0.0) {
      // Capped so that a huge stamp gap (or a tiny rate) cannot overflow the clock's ticks.
      constexpr double kMaxPacingWait_s = 365.0 * 24.0 * 3600.0;
      const double offset_s =
          std::min((recording_.frames[index].rgb_stamp_s - first_stamp_s) / options_.rate, kMaxPacingWait_s);
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

hal::ReadStatus ReplayDepthCamera::read(hal::RgbdFrame& frame, std::chrono::milliseconds wait) {
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
  frame = slots_[held_slot_].frame;
  ++counters_.delivered;
  return hal::ReadStatus::kOk;
}

}  // namespace rankslam::replay
