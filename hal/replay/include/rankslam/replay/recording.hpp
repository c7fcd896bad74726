#pragma once

#include "rankslam/hal/associate.hpp"
#include "rankslam/hal/calibration.hpp"
#include "rankslam/hal/messages.hpp"
#include "rankslam/replay/calibration_file.hpp"

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace rankslam::replay {

/// One associated colour + depth (+ IR) capture of a recording, as files relative to its root.
struct FrameEntry {
  double rgb_stamp_s = 0.0;
  std::string rgb_file;
  double depth_stamp_s = 0.0;
  std::string depth_file;
  std::string ir_file;  ///< Empty when the recording has no IR stream or no IR image near this frame.
};

/// One wide-angle camera image of a recording.
struct ImageEntry {
  double stamp_s = 0.0;
  std::string file;
};

/// Everything a recording directory holds, indexed but not yet decoded.
struct Recording {
  std::filesystem::path root;
  hal::Calibration calibration;
  std::vector<FrameEntry> frames;
  std::vector<ImageEntry> fisheye;
  std::vector<hal::CanFrame> can_frames;
  /// Path of groundtruth.txt when the recording has one.
  std::optional<std::filesystem::path> ground_truth;
  /// Problems that did not stop indexing (unparsable lines, unmatched stamps), each naming its file.
  std::vector<std::string> warnings;
};

/// Largest stamp difference, in seconds, for two streams' samples to count as simultaneous
/// (the TUM benchmark's associate.py default).
inline constexpr double kMaxAssociationGap_s = hal::kDefaultMaxDifference_s;

/// Largest stamp magnitude a recording may hold, s: its nanoseconds fit an int64 (year 2261).
inline constexpr double kMaxStamp_s = 9.2e9;

/// Indexes a recording directory (see README, "Recording format"). Returns an error message
/// naming the file and line on failure, an empty string on success. Every file is read only when
/// it is a regular file within its size bound (hal/regular_file.hpp), so a FIFO, a device or a
/// runaway file is refused, never waited on or read without end.
[[nodiscard]] std::string open_recording(const std::filesystem::path& root, Recording& recording);

/// The TUM benchmark's published calibration for camera "freiburg1", "freiburg2" or "freiburg3";
/// nullopt for any other name.
[[nodiscard]] std::optional<hal::Calibration> tum_calibration(const std::string& camera_name);

}  // namespace rankslam::replay
