#pragma once

#include "rankslam/hal/interfaces.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_stream.hpp"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace rankslam::replay {

/// Plays a recording's colour + depth (+ IR) frames through the DepthCamera interface. Images
/// are decoded on the reader thread into a fixed pool of slots allocated at open(); a missing
/// or corrupt image skips the frame, counts it and names the file in a warning, never stops the
/// replay. Image files are read only when they are regular files of at most 64 MiB whose
/// header gives the calibration's size.
class ReplayDepthCamera final : public hal::DepthCamera, public ReplayStream {
 public:
  ReplayDepthCamera(const Recording& recording, ReplayOptions options);
  ~ReplayDepthCamera() override;
  ReplayDepthCamera(const ReplayDepthCamera&) = delete;
  ReplayDepthCamera& operator=(const ReplayDepthCamera&) = delete;

  [[nodiscard]] std::string open() override;
  [[nodiscard]] const hal::Calibration& calibration() const override { return recording_.calibration; }
  /// Hands out the next frame in recording order. The images stay valid until the next read().
  [[nodiscard]] hal::ReadStatus read(hal::RgbdFrame& frame, std::chrono::milliseconds wait) override;
  void close() override { stop(); }

  /// Frames the replay will deliver at most (after max_frames).
  [[nodiscard]] std::uint32_t frame_count() const { return frame_count_; }

 private:
  struct Slot {
    hal::RgbdFrame frame;
    std::vector<unsigned char> file_buffer;
  };

  [[nodiscard]] std::string decode_into(std::uint32_t index, std::size_t slot) override;
  [[nodiscard]] double stamp_s(std::uint32_t index) const override { return recording_.frames[index].rgb_stamp_s; }
  [[nodiscard]] std::string describe(std::uint32_t index) const override;

  const Recording& recording_;
  std::uint32_t frame_count_ = 0;
  std::array<Slot, kPoolSlots> slots_;
};

/// Plays a recording's wide-angle images (fisheye/, fisheye.txt) through the Camera interface,
/// with the same pool, pacing and skipping as ReplayDepthCamera. Images are decoded as colour
/// (CV_8UC3) of the calibration's `cameras.fisheye` size.
class ReplayImageCamera final : public hal::Camera, public ReplayStream {
 public:
  ReplayImageCamera(const Recording& recording, ReplayOptions options);
  ~ReplayImageCamera() override;
  ReplayImageCamera(const ReplayImageCamera&) = delete;
  ReplayImageCamera& operator=(const ReplayImageCamera&) = delete;

  /// Fails when the recording has no wide-angle images or no calibration for them.
  [[nodiscard]] std::string open() override;
  /// Hands out the next image in recording order; it stays valid until the next read().
  [[nodiscard]] hal::ReadStatus read(hal::ImageFrame& frame, std::chrono::milliseconds wait) override;
  void close() override { stop(); }

  [[nodiscard]] std::uint32_t frame_count() const { return frame_count_; }

 private:
  struct Slot {
    hal::ImageFrame frame;
    std::vector<unsigned char> file_buffer;
  };

  [[nodiscard]] std::string decode_into(std::uint32_t index, std::size_t slot) override;
  [[nodiscard]] double stamp_s(std::uint32_t index) const override { return recording_.fisheye[index].stamp_s; }
  [[nodiscard]] std::string describe(std::uint32_t index) const override;

  const Recording& recording_;
  std::uint32_t frame_count_ = 0;
  std::array<Slot, kPoolSlots> slots_;
};

}  // namespace rankslam::replay
