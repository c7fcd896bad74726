#include "rankslam/replay/replay_camera.hpp"

#include "image_file.hpp"

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>

namespace rankslam::replay {
namespace {

std::int64_t stamp_ns(double stamp_s) { return static_cast<std::int64_t>(std::llround(stamp_s * 1e9)); }

}  // namespace

using detail::decode;
using detail::read_image;

ReplayDepthCamera::ReplayDepthCamera(const Recording& recording, ReplayOptions options)
    : ReplayStream(options), recording_(recording) {}

ReplayDepthCamera::~ReplayDepthCamera() { stop(); }

std::string ReplayDepthCamera::open() {
  stop();
  const auto total = static_cast<std::uint32_t>(recording_.frames.size());
  frame_count_ = options().max_frames > 0 ? std::min(options().max_frames, total) : total;
  if (frame_count_ == 0) return recording_.root.string() + ": no frames to replay";
  const auto& camera = recording_.calibration.rgb;
  for (auto& slot : slots_) {
    // Allocate every image once so decoding reuses the memory.
    slot.frame.rgb.create(camera.height, camera.width, CV_8UC3);
    slot.frame.depth.create(camera.height, camera.width, CV_16UC1);
    slot.frame.ir.release();
    slot.file_buffer.reserve(static_cast<std::size_t>(camera.width) * camera.height * 3);
  }
  return start(frame_count_);
}

std::string ReplayDepthCamera::describe(std::uint32_t index) const {
  return "frame " + std::to_string(index) + " (" + recording_.frames[index].rgb_file + ")";
}

std::string ReplayDepthCamera::decode_into(std::uint32_t index, std::size_t slot_index) {
  Slot& slot = slots_[slot_index];
  const FrameEntry& entry = recording_.frames[index];
  const auto& camera = recording_.calibration.rgb;
  const auto frame_name = describe(index);
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
  if (options().load_ir && !entry.ir_file.empty()) {
    const auto ir_path = recording_.root / entry.ir_file;
    // A bad IR image costs the IR stream for this frame, not the frame.
    if (!read_image(ir_path, camera, slot.file_buffer, header).empty() ||
        !decode(slot.file_buffer, cv::IMREAD_GRAYSCALE, slot.frame.ir) || slot.frame.ir.size() != slot.frame.rgb.size()) {
      slot.frame.ir.release();
      warn(ir_path.string() + ": missing or undecodable IR image, " + frame_name + " has no IR");
    }
  }
  slot.frame.sequence = index;
  slot.frame.stamp_s = entry.rgb_stamp_s;
  slot.frame.stamp_ns = stamp_ns(entry.rgb_stamp_s);
  return {};
}

hal::ReadStatus ReplayDepthCamera::read(hal::RgbdFrame& frame, std::chrono::milliseconds wait) {
  std::size_t slot = 0;
  const hal::ReadStatus status = next(slot, wait);
  if (status == hal::ReadStatus::kOk) frame = slots_[slot].frame;
  return status;
}

ReplayImageCamera::ReplayImageCamera(const Recording& recording, ReplayOptions options)
    : ReplayStream(options), recording_(recording) {}

ReplayImageCamera::~ReplayImageCamera() { stop(); }

std::string ReplayImageCamera::open() {
  stop();
  if (!recording_.calibration.fisheye) {
    return recording_.calibration.source + ": no cameras.fisheye calibration for the wide-angle images";
  }
  // All of them: the consumer takes the images by stamp and stops where the colour frames end.
  frame_count_ = static_cast<std::uint32_t>(recording_.fisheye.size());
  if (frame_count_ == 0) return (recording_.root / "fisheye.txt").string() + ": no wide-angle images to replay";
  const auto& camera = *recording_.calibration.fisheye;
  for (auto& slot : slots_) {
    slot.frame.image.create(camera.height, camera.width, CV_8UC3);
    slot.file_buffer.reserve(static_cast<std::size_t>(camera.width) * camera.height * 3);
  }
  return start(frame_count_);
}

std::string ReplayImageCamera::describe(std::uint32_t index) const {
  return "wide-angle image " + std::to_string(index) + " (" + recording_.fisheye[index].file + ")";
}

std::string ReplayImageCamera::decode_into(std::uint32_t index, std::size_t slot_index) {
  Slot& slot = slots_[slot_index];
  const ImageEntry& entry = recording_.fisheye[index];
  const auto& camera = *recording_.calibration.fisheye;
  const auto path = recording_.root / entry.file;
  hal::ImageHeader header;
  if (auto error = read_image(path, camera, slot.file_buffer, header); !error.empty()) {
    return error + ", " + describe(index) + " skipped";
  }
  if (!decode(slot.file_buffer, cv::IMREAD_COLOR, slot.frame.image) || slot.frame.image.cols != camera.width ||
      slot.frame.image.rows != camera.height) {
    return path.string() + ": not a decodable " + std::to_string(camera.width) + "x" + std::to_string(camera.height) +
           " image, " + describe(index) + " skipped";
  }
  slot.frame.sequence = index;
  slot.frame.stamp_s = entry.stamp_s;
  slot.frame.stamp_ns = stamp_ns(entry.stamp_s);
  return {};
}

hal::ReadStatus ReplayImageCamera::read(hal::ImageFrame& frame, std::chrono::milliseconds wait) {
  std::size_t slot = 0;
  const hal::ReadStatus status = next(slot, wait);
  if (status == hal::ReadStatus::kOk) frame = slots_[slot].frame;
  return status;
}

}  // namespace rankslam::replay
