#pragma once

#include "rankslam/hal/interfaces.hpp"

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace rankslam::openni2 {

/// Colour pixel formats the driver asks the device for; every one becomes BGR.
enum class ColorFormat : std::uint8_t {
  kRgb888,  ///< Packed RGB, 3 bytes per pixel (PrimeSense/Kinect default).
  kYuv422,  ///< OpenNI's YUV422 (UYVY byte order).
  kYuyv,    ///< YUYV byte order.
};

/// Depth units the driver asks the device for.
enum class DepthFormat : std::uint8_t {
  kMillimetre,        ///< 1 mm per unit: Calibration::depth_scale 1000.
  kHundredMicrometre, ///< 0.1 mm per unit: Calibration::depth_scale 10000.
};

/// Set-up of an OpenNI2 camera; fixed after construction.
struct OpenNI2Options {
  /// Device URI as OpenNI2 names it (the PS1080 driver: "1d27/0601@1/5"), the path of an .oni
  /// recording (played through OpenNI2's file device), or empty for the first device.
  std::string uri;
  /// Video mode of colour, depth and IR streams: the device must offer exactly this mode.
  /// A recording (.oni) plays in the mode it was recorded in; these are then not applied.
  int width = 640;
  int height = 480;
  int fps = 30;
  ColorFormat color_format = ColorFormat::kRgb888;
  DepthFormat depth_format = DepthFormat::kMillimetre;
  /// Open the IR stream as well. PrimeSense devices cannot stream IR and colour at once; their
  /// refusal is reported by open().
  bool ir = false;
  /// Register depth to colour in the device (IMAGE_REGISTRATION_DEPTH_TO_COLOR) when it can.
  bool registration = true;
  /// Ask the device to deliver colour and depth frames in synchronised pairs.
  bool sync = true;
  /// Largest colour-depth stamp difference of a pair; unpaired frames are discarded and counted.
  std::chrono::milliseconds max_pair_gap{20};
  /// Intrinsics to use instead of those derived from the device's field of view. Needed for
  /// devices and recordings that report no field of view (OpenNI2's DummyDevice).
  std::optional<hal::Calibration> calibration;
  /// After a fault (unplug, device error, stall) reopen on later reads at most this often.
  bool reopen_after_fault = true;
  std::chrono::milliseconds reopen_interval{1000};
  /// No frame for this long while streaming counts as a fault (a device that stopped talking).
  std::chrono::milliseconds stall_timeout{2000};
  /// Recordings only: playback speed as a multiple of the recorded rate (0 = as fast as
  /// OpenNI2 can) and whether to loop at the end (otherwise read() reports kEndOfStream).
  double playback_speed = 1.0;
  bool playback_repeat = false;
};

/// What the device agreed to.
struct OpenNI2Stream {
  std::string uri;          ///< URI of the opened device.
  std::string name;         ///< Vendor and name as OpenNI2 reports them.
  bool is_file = false;     ///< An .oni recording played through the file device.
  int width = 0;
  int height = 0;
  int fps = 0;
  int color_pixel_format = 0;  ///< OpenNI2 pixel format codes.
  int depth_pixel_format = 0;
  int ir_pixel_format = 0;     ///< 0 when the IR stream is off.
  bool registered = false;     ///< Depth is registered to colour by the device.
  bool synchronised = false;   ///< The device's depth-colour frame sync is on.
  bool mirroring_off = false;  ///< Mirroring is known to be off (property set or reported).
  int recorded_frames = 0;     ///< Recordings: depth frames in the file.
};

/// Counters since open().
struct OpenNI2Counters {
  std::uint64_t frames = 0;    ///< Frame pairs handed to the caller.
  std::uint64_t timeouts = 0;  ///< Reads that ended with kTimeout.
  std::uint64_t dropped = 0;   ///< Depth frames the device skipped (gaps in the frame index).
  std::uint64_t unpaired = 0;  ///< Colour or depth frames discarded for want of a partner.
  std::uint64_t corrupt = 0;   ///< Frames of an unexpected size or format.
  std::uint64_t faults = 0;    ///< Reads that returned kFault.
  std::uint64_t reopens = 0;   ///< Successful reopens after a fault.
};

/// hal::DepthCamera on an OpenNI2 device.
///
/// read() waits in OpenNI2's waitForAnyStream at most `wait`, copies each arriving frame into
/// images allocated at open() (colour converted to BGR) and returns when a colour and a depth
/// frame within max_pair_gap form a pair. stamp_ns is the depth frame's device stamp mapped to
/// CLOCK_MONOTONIC: the offset between device and host clock is the smallest arrival delay seen,
/// so transport jitter does not enter the stamps. A device that disappears (OpenNI2's
/// disconnect or error event), fails, or stalls makes read() return kFault and closes it; later
/// reads reopen it at most every reopen_interval. Until one succeeds, each read sleeps until an
/// attempt is due or its `wait` ends and returns kFault, so a caller's read loop does not spin.
/// A recording that is truncated or overwritten under the playback ends in kFault (the file
/// device goes silent); one deleted or replaced by a new file plays on to its end, as the file
/// device keeps the old file open.
///
/// OpenNI2 is initialised once per process and never shut down here. Other code may pair its own
/// openni::OpenNI::initialize() and shutdown(); an unbalanced shutdown() frees this camera's
/// streams inside libOpenNI2, and its next read() crashes there.
///
/// One thread at a time.
class OpenNI2Camera final : public hal::DepthCamera {
 public:
  explicit OpenNI2Camera(OpenNI2Options options);
  ~OpenNI2Camera() override;
  OpenNI2Camera(const OpenNI2Camera&) = delete;
  OpenNI2Camera& operator=(const OpenNI2Camera&) = delete;

  /// Initialises OpenNI2, opens the device, selects the modes, starts the streams. Empty on
  /// success, otherwise what went wrong, naming the device or file.
  [[nodiscard]] std::string open() override;
  [[nodiscard]] const hal::Calibration& calibration() const override;
  [[nodiscard]] hal::ReadStatus read(hal::RgbdFrame& frame, std::chrono::milliseconds wait) override;
  void close() override;

  [[nodiscard]] const OpenNI2Options& options() const;
  [[nodiscard]] const OpenNI2Stream& stream() const;
  [[nodiscard]] const OpenNI2Counters& counters() const;
  /// True while the device is open and streaming (false after a fault until a reopen).
  [[nodiscard]] bool is_open() const;
  /// One line for the start-up log: device, modes, registration, sync, mirroring.
  [[nodiscard]] std::string describe() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// The directory OpenNI2 loads its device drivers from: the [Drivers] Repository of
/// /etc/openni2/OpenNI.ini when set, otherwise OpenNI2/Drivers beside libOpenNI2.so. OpenNI2
/// 2.2 takes no other setting, so this is what error messages name.
[[nodiscard]] std::string openni2_driver_directory();

}  // namespace rankslam::openni2
