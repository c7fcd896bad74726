#include "rankslam/openni2/openni2_camera.hpp"

#include "rankslam/hal/reopen_wait.hpp"

#include <OpenNI.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <dlfcn.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <thread>
#include <utility>

namespace rankslam::openni2 {
namespace {

constexpr std::int64_t kNsPerUs = 1000;

std::int64_t monotonic_ns() { return hal::MonotonicClock{}.now_ns(); }

std::string last_error() {
  const char* text = openni::OpenNI::getExtendedError();
  std::string error = text != nullptr ? text : "";
  // OpenNI2 prefixes and ends its messages with whitespace.
  const auto first = error.find_first_not_of(" \t\r\n");
  const auto last = error.find_last_not_of(" \t\r\n");
  return first == std::string::npos ? std::string("no detail from OpenNI2") : error.substr(first, last - first + 1);
}

std::string format_name(openni::PixelFormat format) {
  switch (format) {
    case openni::PIXEL_FORMAT_DEPTH_1_MM: return "DEPTH_1_MM";
    case openni::PIXEL_FORMAT_DEPTH_100_UM: return "DEPTH_100_UM";
    case openni::PIXEL_FORMAT_SHIFT_9_2: return "SHIFT_9_2";
    case openni::PIXEL_FORMAT_SHIFT_9_3: return "SHIFT_9_3";
    case openni::PIXEL_FORMAT_RGB888: return "RGB888";
    case openni::PIXEL_FORMAT_YUV422: return "YUV422";
    case openni::PIXEL_FORMAT_GRAY8: return "GRAY8";
    case openni::PIXEL_FORMAT_GRAY16: return "GRAY16";
    case openni::PIXEL_FORMAT_JPEG: return "JPEG";
    case openni::PIXEL_FORMAT_YUYV: return "YUYV";
  }
  return "format " + std::to_string(static_cast<int>(format));
}

std::string mode_text(const openni::VideoMode& mode) {
  return std::to_string(mode.getResolutionX()) + "x" + std::to_string(mode.getResolutionY()) + "@" +
         std::to_string(mode.getFps()) + " " + format_name(mode.getPixelFormat());
}

const char* sensor_name(openni::SensorType type) {
  switch (type) {
    case openni::SENSOR_COLOR: return "colour";
    case openni::SENSOR_DEPTH: return "depth";
    case openni::SENSOR_IR: return "IR";
  }
  return "sensor";
}

bool is_recording_path(const std::string& uri) {
  return uri.size() > 4 && uri.compare(uri.size() - 4, 4, ".oni") == 0;
}

// OpenNI2 keeps process-wide state and loads its drivers once. It is initialised on first use
// and never shut down: some drivers (the DummyDevice) keep producing on their own threads for a
// moment after a stream stops, and unloading the driver under them would crash the process.
std::string ensure_openni_initialised() {
  static std::once_flag once;
  static std::string error;
  std::call_once(once, [] {
    if (openni::OpenNI::initialize() != openni::STATUS_OK) {
      error = "OpenNI2 initialisation failed (" + last_error() + "); drivers are loaded from " +
              openni2_driver_directory();
    }
  });
  return error;
}

}  // namespace

std::string openni2_driver_directory() {
  std::ifstream ini("/etc/openni2/OpenNI.ini");
  std::string line;
  std::string section;
  std::string repository;
  while (std::getline(ini, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    if (line.empty() || line[0] == ';') continue;
    if (line[0] == '[') {
      section = line;
      continue;
    }
    if (section == "[Drivers]" && line.rfind("Repository=", 0) == 0) repository = line.substr(11);
  }
  Dl_info info{};
  std::filesystem::path library_dir;
  if (dladdr(reinterpret_cast<void*>(&oniInitialize), &info) != 0 && info.dli_fname != nullptr) {
    library_dir = std::filesystem::path(info.dli_fname).parent_path();
  }
  if (!repository.empty() && repository[0] == '/') return repository;
  return (library_dir / (repository.empty() ? "OpenNI2/Drivers" : repository)).string();
}

struct OpenNI2Camera::State : openni::OpenNI::DeviceDisconnectedListener,
                              openni::OpenNI::DeviceStateChangedListener {
  explicit State(OpenNI2Options opts) : options(std::move(opts)) {}

  void onDeviceDisconnected(const openni::DeviceInfo* info) override {
    if (info != nullptr && info->getUri() == device_uri_copy()) lost.store(true);
  }
  void onDeviceStateChanged(const openni::DeviceInfo* info, openni::DeviceState state) override {
    if (info == nullptr || info->getUri() != device_uri_copy()) return;
    if (state == openni::DEVICE_STATE_ERROR) lost.store(true);
    if (state == openni::DEVICE_STATE_EOF) end_of_file.store(true);
  }
  std::string device_uri_copy() {
    std::lock_guard lock(uri_mutex);
    return device_uri;
  }

  std::string open_device();
  void close_device();
  bool ensure_open();
  /// While faulted: sleeps until the next reopen attempt is due or `deadline_ns`, whichever is
  /// first, and makes that attempt. True when the device is open again.
  bool wait_for_reopen(std::int64_t deadline_ns);
  hal::ReadStatus fault();
  /// Copies a frame into the pending image of its stream; false when unusable.
  bool take(openni::SensorType type, const openni::VideoFrameRef& frame, cv::Mat& image);
  std::int64_t to_monotonic(std::uint64_t device_us, std::int64_t arrival_ns);

  OpenNI2Options options;
  OpenNI2Stream stream;
  OpenNI2Counters counters;
  hal::Calibration calibration;

  openni::Device device;
  openni::VideoStream color;
  openni::VideoStream depth;
  openni::VideoStream ir;
  std::array<openni::VideoStream*, 3> streams{};
  int stream_count = 0;
  openni::VideoFrameRef frame_ref;

  bool opened = false;      // open() succeeded and close() was not called since
  bool streaming = false;   // the device is open now
  bool listening = false;
  std::int64_t last_reopen_attempt_ns = 0;
  std::int64_t last_frame_ns = 0;

  std::mutex uri_mutex;  // the listeners run on OpenNI2's threads
  std::string device_uri;
  std::atomic<bool> lost{false};
  std::atomic<bool> end_of_file{false};

  // Device-to-monotonic stamp mapping.
  bool have_offset = false;
  std::int64_t offset_ns = 0;
  std::uint64_t last_device_us = 0;
  std::int64_t last_stamp_ns = 0;

  // Images allocated at open(). Colour and depth frames wait in short histories until a frame
  // of the other stream within max_pair_gap arrives: without device sync one stream may lead
  // the other by a frame, and pairing only the latest of each would then never match.
  struct Pending {
    cv::Mat image;
    std::int64_t stamp_ns = 0;
    bool valid = false;
    std::uint32_t index = 0;  // the device's frame index
  };
  static constexpr std::size_t kHistory = 3;
  std::array<Pending, kHistory> rgb_history, depth_history;
  Pending pending_ir;
  cv::Mat out_rgb, out_depth, out_ir;
  /// The slot of `history` a new frame goes to: a free one, else the oldest (counted unpaired).
  Pending& slot_for_new(std::array<Pending, kHistory>& history);
  /// Drops every waiting frame older than `stamp_ns` (they can no longer pair) and counts them.
  void drop_older(std::array<Pending, kHistory>& history, std::int64_t stamp_ns);
  std::uint32_t depth_index = 0;
  bool have_depth_index = false;
  int last_depth_frame_index = 0;
};

std::string OpenNI2Camera::State::open_device() {
  const std::string where = options.uri.empty() ? std::string("OpenNI2 first device") : "OpenNI2 device '" + options.uri + "'";
  if (is_recording_path(options.uri)) {
    std::error_code ec;
    if (!std::filesystem::is_regular_file(options.uri, ec)) return options.uri + ": no such recording file";
  }
  const char* uri = options.uri.empty() ? openni::ANY_DEVICE : options.uri.c_str();
  if (device.open(uri) != openni::STATUS_OK) {
    return where + ": cannot open (" + last_error() + "; drivers in " + openni2_driver_directory() + ")";
  }
  stream = {};
  stream.uri = device.getDeviceInfo().getUri();
  stream.name = std::string(device.getDeviceInfo().getVendor()) + " " + device.getDeviceInfo().getName();
  stream.is_file = device.isFile();
  {
    std::lock_guard lock(uri_mutex);
    device_uri = stream.uri;
  }
  lost = false;
  end_of_file = false;
  const auto fail = [&](const std::string& what) {
    close_device();
    return where + ": " + what;
  };

  if (stream.is_file) {
    openni::PlaybackControl* playback = device.getPlaybackControl();
    if (playback == nullptr) return fail("file device without playback control");
    if (playback->setSpeed(static_cast<float>(options.playback_speed)) != openni::STATUS_OK ||
        playback->setRepeatEnabled(options.playback_repeat) != openni::STATUS_OK) {
      return fail("cannot set playback speed or repeat (" + last_error() + ")");
    }
  }

  const auto wanted_format = [&](openni::SensorType type) {
    switch (type) {
      case openni::SENSOR_DEPTH:
        return options.depth_format == DepthFormat::kMillimetre ? openni::PIXEL_FORMAT_DEPTH_1_MM
                                                                : openni::PIXEL_FORMAT_DEPTH_100_UM;
      case openni::SENSOR_COLOR:
        return options.color_format == ColorFormat::kRgb888   ? openni::PIXEL_FORMAT_RGB888
               : options.color_format == ColorFormat::kYuv422 ? openni::PIXEL_FORMAT_YUV422
                                                              : openni::PIXEL_FORMAT_YUYV;
      case openni::SENSOR_IR: return openni::PIXEL_FORMAT_GRAY16;
    }
    return openni::PIXEL_FORMAT_GRAY16;
  };

  // Creates a stream and selects its mode: exactly the configured one on a live device, the
  // recorded one on a file (a file device cannot change modes).
  const auto create = [&](openni::SensorType type, openni::VideoStream& video) -> std::string {
    const openni::SensorInfo* info = device.getSensorInfo(type);
    if (info == nullptr) return std::string("has no ") + sensor_name(type) + " sensor";
    if (video.create(device, type) != openni::STATUS_OK) {
      return std::string("cannot create the ") + sensor_name(type) + " stream (" + last_error() + ")";
    }
    if (stream.is_file) return {};
    const auto& modes = info->getSupportedVideoModes();
    const openni::PixelFormat format = wanted_format(type);
    for (int i = 0; i < modes.getSize(); ++i) {
      const openni::VideoMode& mode = modes[i];
      const bool ir_gray8 = type == openni::SENSOR_IR && mode.getPixelFormat() == openni::PIXEL_FORMAT_GRAY8;
      if (mode.getResolutionX() != options.width || mode.getResolutionY() != options.height ||
          mode.getFps() != options.fps || (mode.getPixelFormat() != format && !ir_gray8)) {
        continue;
      }
      const openni::VideoMode current = video.getVideoMode();
      if (current.getResolutionX() == mode.getResolutionX() && current.getResolutionY() == mode.getResolutionY() &&
          current.getFps() == mode.getFps() && current.getPixelFormat() == mode.getPixelFormat()) {
        return {};
      }
      if (video.setVideoMode(mode) != openni::STATUS_OK) {
        return std::string("refused the ") + sensor_name(type) + " mode " + mode_text(mode) + " (" + last_error() + ")";
      }
      return {};
    }
    std::string offered;
    for (int i = 0; i < modes.getSize(); ++i) offered += (i == 0 ? "" : ", ") + mode_text(modes[i]);
    return std::string("offers no ") + sensor_name(type) + " mode " + std::to_string(options.width) + "x" +
           std::to_string(options.height) + "@" + std::to_string(options.fps) + " " + format_name(format) +
           " (offers: " + (offered.empty() ? "none" : offered) + ")";
  };

  if (auto error = create(openni::SENSOR_DEPTH, depth); !error.empty()) return fail(error);
  if (auto error = create(openni::SENSOR_COLOR, color); !error.empty()) return fail(error);
  if (options.ir) {
    if (auto error = create(openni::SENSOR_IR, ir); !error.empty()) return fail(error);
  }

  const openni::VideoMode depth_mode = depth.getVideoMode();
  const openni::VideoMode color_mode = color.getVideoMode();
  stream.width = depth_mode.getResolutionX();
  stream.height = depth_mode.getResolutionY();
  stream.fps = depth_mode.getFps();
  stream.depth_pixel_format = depth_mode.getPixelFormat();
  stream.color_pixel_format = color_mode.getPixelFormat();
  if (color_mode.getResolutionX() != stream.width || color_mode.getResolutionY() != stream.height) {
    return fail("colour " + mode_text(color_mode) + " and depth " + mode_text(depth_mode) +
                " differ in size; registered frames need one size");
  }
  if (depth_mode.getPixelFormat() != openni::PIXEL_FORMAT_DEPTH_1_MM &&
      depth_mode.getPixelFormat() != openni::PIXEL_FORMAT_DEPTH_100_UM) {
    return fail("depth format " + format_name(depth_mode.getPixelFormat()) + " is not metric (DEPTH_1_MM or DEPTH_100_UM needed)");
  }
  const auto cf = color_mode.getPixelFormat();
  if (cf != openni::PIXEL_FORMAT_RGB888 && cf != openni::PIXEL_FORMAT_YUV422 && cf != openni::PIXEL_FORMAT_YUYV) {
    return fail("colour format " + format_name(cf) + " is not supported (RGB888, YUV422 or YUYV)");
  }
  if (options.ir) {
    const openni::VideoMode ir_mode = ir.getVideoMode();
    stream.ir_pixel_format = ir_mode.getPixelFormat();
    if (ir_mode.getResolutionX() != stream.width || ir_mode.getResolutionY() != stream.height ||
        (ir_mode.getPixelFormat() != openni::PIXEL_FORMAT_GRAY16 && ir_mode.getPixelFormat() != openni::PIXEL_FORMAT_GRAY8)) {
      return fail("IR mode " + mode_text(ir_mode) + " does not match depth " + mode_text(depth_mode) + " (GRAY8/GRAY16 of the same size needed)");
    }
  }

  // Registration, sync and mirroring: applied where the device supports them, reported otherwise.
  if (options.registration && device.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
    if (device.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) != openni::STATUS_OK) {
      return fail("refused depth-to-colour registration (" + last_error() + ")");
    }
    stream.registered = true;
  } else if (stream.is_file) {
    // A recording keeps the registration it was made with; the file device reports none.
    stream.registered = device.getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  }
  stream.synchronised = options.sync && device.setDepthColorSyncEnabled(true) == openni::STATUS_OK;
  for (openni::VideoStream* video : {&depth, &color, options.ir ? &ir : nullptr}) {
    if (video == nullptr) continue;
    if (video->isPropertySupported(openni::STREAM_PROPERTY_MIRRORING) && !stream.is_file) {
      if (video->setMirroringEnabled(false) != openni::STATUS_OK) return fail("cannot turn mirroring off (" + last_error() + ")");
    }
  }
  stream.mirroring_off = !depth.getMirroringEnabled() && !color.getMirroringEnabled();

  // Calibration: configured, or derived from the colour camera's field of view.
  if (options.calibration) {
    calibration = *options.calibration;
    if (calibration.rgb.width != stream.width || calibration.rgb.height != stream.height) {
      return fail("the calibration is for " + std::to_string(calibration.rgb.width) + "x" +
                  std::to_string(calibration.rgb.height) + " but the streams are " + std::to_string(stream.width) + "x" +
                  std::to_string(stream.height));
    }
  } else {
    const double hfov = color.getHorizontalFieldOfView();
    const double vfov = color.getVerticalFieldOfView();
    if (!(hfov > 0.0 && hfov < 3.1) || !(vfov > 0.0 && vfov < 3.1)) {
      return fail("reports no field of view; give a calibration (camera.calibration)");
    }
    calibration = hal::Calibration{};
    calibration.source = "field of view reported by " + stream.name;
    calibration.rgb.width = stream.width;
    calibration.rgb.height = stream.height;
    calibration.rgb.fx = 0.5 * stream.width / std::tan(0.5 * hfov);
    calibration.rgb.fy = 0.5 * stream.height / std::tan(0.5 * vfov);
    calibration.rgb.cx = 0.5 * (stream.width - 1);
    calibration.rgb.cy = 0.5 * (stream.height - 1);
  }
  calibration.depth_scale = depth_mode.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM ? 1000.0 : 10000.0;

  if (stream.is_file) {
    openni::PlaybackControl* playback = device.getPlaybackControl();
    stream.recorded_frames = playback->getNumberOfFrames(depth);
  }

  try {
    for (auto& pending : rgb_history) pending = {cv::Mat(stream.height, stream.width, CV_8UC3), 0, false, 0};
    for (auto& pending : depth_history) pending = {cv::Mat(stream.height, stream.width, CV_16UC1), 0, false, 0};
    out_rgb.create(stream.height, stream.width, CV_8UC3);
    out_depth.create(stream.height, stream.width, CV_16UC1);
    pending_ir.valid = false;
    const int ir_type = stream.ir_pixel_format == openni::PIXEL_FORMAT_GRAY8 ? CV_8UC1 : CV_16UC1;
    for (cv::Mat* image : {&pending_ir.image, &out_ir}) {
      if (options.ir) {
        image->create(stream.height, stream.width, ir_type);
      } else {
        image->release();
      }
    }
  } catch (const cv::Exception& error) {
    return fail(std::string("cannot allocate the images: ") + error.what());
  }

  stream_count = 0;
  for (openni::VideoStream* video : {&depth, &color, options.ir ? &ir : nullptr}) {
    if (video == nullptr) continue;
    if (video->start() != openni::STATUS_OK) {
      return fail(std::string("cannot start the ") +
                  (video == &depth ? "depth" : video == &color ? "colour" : "IR (PrimeSense devices stream IR or colour, not both)") +
                  " stream (" + last_error() + ")");
    }
    streams[static_cast<std::size_t>(stream_count++)] = video;
  }
  have_offset = false;
  have_depth_index = false;
  last_depth_frame_index = 0;
  last_frame_ns = monotonic_ns();
  streaming = true;
  return {};
}

void OpenNI2Camera::State::close_device() {
  for (openni::VideoStream* video : {&depth, &color, &ir}) {
    if (video->isValid()) video->stop();
  }
  // Some drivers (OpenNI2's DummyDevice) only flag their producer thread at stop() and let it
  // finish its current frame; destroying the stream under it would free memory it still uses.
  if (depth.isValid() || color.isValid()) std::this_thread::sleep_for(std::chrono::milliseconds(60));
  for (openni::VideoStream* video : {&depth, &color, &ir}) {
    if (video->isValid()) video->destroy();
  }
  frame_ref.release();
  if (device.isValid()) device.close();
  stream_count = 0;
  streaming = false;
}

bool OpenNI2Camera::State::ensure_open() {
  if (streaming) return true;
  if (!opened || !options.reopen_after_fault) return false;
  const std::int64_t now = monotonic_ns();
  const std::int64_t interval_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(options.reopen_interval).count();
  if (last_reopen_attempt_ns != 0 && now - last_reopen_attempt_ns < interval_ns) return false;
  last_reopen_attempt_ns = now;
  if (!open_device().empty()) return false;
  ++counters.reopens;
  return true;
}

bool OpenNI2Camera::State::wait_for_reopen(std::int64_t deadline_ns) {
  if (!opened) return false;  // never opened or closed: waiting changes nothing
  return hal::sleep_until_reopen_due(last_reopen_attempt_ns, options.reopen_interval, options.reopen_after_fault, deadline_ns) && ensure_open();
}

hal::ReadStatus OpenNI2Camera::State::fault() {
  close_device();
  last_reopen_attempt_ns = monotonic_ns();
  ++counters.faults;
  return hal::ReadStatus::kFault;
}

std::int64_t OpenNI2Camera::State::to_monotonic(std::uint64_t device_us, std::int64_t arrival_ns) {
  const auto device_ns = static_cast<std::int64_t>(device_us) * kNsPerUs;
  // A device clock that restarts (reopen, a looping recording) needs a new offset.
  if (have_offset && device_us + 1'000'000 < last_device_us) have_offset = false;
  last_device_us = device_us;
  const std::int64_t delay = arrival_ns - device_ns;
  if (!have_offset || delay < offset_ns) offset_ns = delay;
  have_offset = true;
  std::int64_t stamp = device_ns + offset_ns;
  if (stamp <= last_stamp_ns) stamp = last_stamp_ns + 1;  // strictly increasing for consumers
  return stamp;
}

OpenNI2Camera::State::Pending& OpenNI2Camera::State::slot_for_new(std::array<Pending, kHistory>& history) {
  Pending* oldest = &history[0];
  for (auto& pending : history) {
    if (!pending.valid) return pending;
    if (pending.stamp_ns < oldest->stamp_ns) oldest = &pending;
  }
  ++counters.unpaired;
  oldest->valid = false;
  return *oldest;
}

void OpenNI2Camera::State::drop_older(std::array<Pending, kHistory>& history, std::int64_t stamp_ns) {
  for (auto& pending : history) {
    if (pending.valid && pending.stamp_ns < stamp_ns) {
      pending.valid = false;
      ++counters.unpaired;
    }
  }
}

bool OpenNI2Camera::State::take(openni::SensorType type, const openni::VideoFrameRef& frame, cv::Mat& image) {
  const int width = frame.getWidth();
  const int height = frame.getHeight();
  const int stride = frame.getStrideInBytes();
  const auto format = frame.getVideoMode().getPixelFormat();
  const void* data = frame.getData();
  if (width != stream.width || height != stream.height || data == nullptr) return false;
  auto* bytes = static_cast<std::uint8_t*>(const_cast<void*>(data));  // cv::Mat headers take non-const
  const auto fits = [&](int bytes_per_pixel) {
    return stride >= width * bytes_per_pixel && frame.getDataSize() >= stride * (height - 1) + width * bytes_per_pixel;
  };
  switch (type) {
    case openni::SENSOR_COLOR:
      if (format == openni::PIXEL_FORMAT_RGB888 && fits(3)) {
        cv::cvtColor(cv::Mat(height, width, CV_8UC3, bytes, static_cast<std::size_t>(stride)), image, cv::COLOR_RGB2BGR);
      } else if (format == openni::PIXEL_FORMAT_YUV422 && fits(2)) {
        cv::cvtColor(cv::Mat(height, width, CV_8UC2, bytes, static_cast<std::size_t>(stride)), image, cv::COLOR_YUV2BGR_UYVY);
      } else if (format == openni::PIXEL_FORMAT_YUYV && fits(2)) {
        cv::cvtColor(cv::Mat(height, width, CV_8UC2, bytes, static_cast<std::size_t>(stride)), image, cv::COLOR_YUV2BGR_YUYV);
      } else {
        return false;
      }
      return true;
    case openni::SENSOR_DEPTH:
      if ((format != openni::PIXEL_FORMAT_DEPTH_1_MM && format != openni::PIXEL_FORMAT_DEPTH_100_UM) || !fits(2)) return false;
      cv::Mat(height, width, CV_16UC1, bytes, static_cast<std::size_t>(stride)).copyTo(image);
      return true;
    case openni::SENSOR_IR:
      if (format == openni::PIXEL_FORMAT_GRAY16 && image.type() == CV_16UC1 && fits(2)) {
        cv::Mat(height, width, CV_16UC1, bytes, static_cast<std::size_t>(stride)).copyTo(image);
      } else if (format == openni::PIXEL_FORMAT_GRAY8 && image.type() == CV_8UC1 && fits(1)) {
        cv::Mat(height, width, CV_8UC1, bytes, static_cast<std::size_t>(stride)).copyTo(image);
      } else {
        return false;
      }
      return true;
  }
  return false;
}

OpenNI2Camera::OpenNI2Camera(OpenNI2Options options) : state_(std::make_unique<State>(std::move(options))) {}

OpenNI2Camera::~OpenNI2Camera() {
  State* state = state_.get();
  if (state == nullptr) return;
  close();
  if (state->listening) {
    openni::OpenNI::removeDeviceDisconnectedListener(state);
    openni::OpenNI::removeDeviceStateChangedListener(state);
  }
}

std::string OpenNI2Camera::open() {
  close();
  State& s = *state_;
  if (s.options.width <= 0 || s.options.height <= 0 || s.options.fps <= 0) {
    return "openni2: video mode " + std::to_string(s.options.width) + "x" + std::to_string(s.options.height) + "@" +
           std::to_string(s.options.fps) + " must be positive";
  }
  if (!(s.options.playback_speed >= 0.0) || !std::isfinite(s.options.playback_speed)) {
    return "openni2: playback speed must be 0 (as fast as possible) or positive";
  }
  if (auto error = ensure_openni_initialised(); !error.empty()) return error;
  if (!s.listening) {
    openni::OpenNI::addDeviceDisconnectedListener(&s);
    openni::OpenNI::addDeviceStateChangedListener(&s);
    s.listening = true;
  }
  s.counters = {};
  s.last_stamp_ns = 0;
  if (auto error = s.open_device(); !error.empty()) return error;
  s.opened = true;
  return {};
}

void OpenNI2Camera::close() {
  state_->close_device();
  state_->opened = false;
}

const hal::Calibration& OpenNI2Camera::calibration() const { return state_->calibration; }
const OpenNI2Options& OpenNI2Camera::options() const { return state_->options; }
const OpenNI2Stream& OpenNI2Camera::stream() const { return state_->stream; }
const OpenNI2Counters& OpenNI2Camera::counters() const { return state_->counters; }
bool OpenNI2Camera::is_open() const { return state_->streaming; }

hal::ReadStatus OpenNI2Camera::read(hal::RgbdFrame& frame, std::chrono::milliseconds wait) {
  State& s = *state_;
  const std::int64_t wait_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::max(wait, std::chrono::milliseconds{0})).count();
  const std::int64_t deadline_ns = monotonic_ns() + wait_ns;
  // A lasting fault waits out `wait` (or until a reopen is due) so that callers' read loops do not spin.
  if (!s.ensure_open() && !s.wait_for_reopen(deadline_ns)) {
    ++s.counters.faults;
    return hal::ReadStatus::kFault;
  }
  const std::int64_t gap_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(s.options.max_pair_gap).count();
  const std::int64_t stall_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(s.options.stall_timeout).count();
  for (;;) {
    if (s.lost.load()) return s.fault();
    const std::int64_t remaining_ns = std::max<std::int64_t>(0, deadline_ns - monotonic_ns());
    int ready = -1;
    const openni::Status status = openni::OpenNI::waitForAnyStream(
        s.streams.data(), s.stream_count, &ready, static_cast<int>((remaining_ns + 999'999) / 1'000'000));
    const std::int64_t now = monotonic_ns();
    if (status == openni::STATUS_TIME_OUT || (status == openni::STATUS_OK && ready < 0)) {
      if (s.lost.load()) return s.fault();
      const bool file_done = s.stream.is_file && !s.options.playback_repeat &&
                             (s.end_of_file.load() || (s.stream.recorded_frames > 0 &&
                                                       s.last_depth_frame_index >= s.stream.recorded_frames));
      if (file_done) return hal::ReadStatus::kEndOfStream;
      if (now - s.last_frame_ns > stall_ns) return s.fault();
      if (now < deadline_ns) continue;
      if (wait_ns == 0) return hal::ReadStatus::kNoData;
      ++s.counters.timeouts;
      return hal::ReadStatus::kTimeout;
    }
    if (status != openni::STATUS_OK || ready >= s.stream_count) return s.fault();
    openni::VideoStream* video = s.streams[static_cast<std::size_t>(ready)];
    if (video->readFrame(&s.frame_ref) != openni::STATUS_OK) return s.fault();
    s.last_frame_ns = now;
    const openni::SensorType type = video == &s.depth ? openni::SENSOR_DEPTH
                                    : video == &s.color ? openni::SENSOR_COLOR
                                                        : openni::SENSOR_IR;
    const std::int64_t stamp = s.to_monotonic(s.frame_ref.getTimestamp(), now);
    if (type == openni::SENSOR_DEPTH) {
      const auto index = static_cast<std::uint32_t>(s.frame_ref.getFrameIndex());
      s.last_depth_frame_index = s.frame_ref.getFrameIndex();
      if (s.have_depth_index && index > s.depth_index + 1 && index - s.depth_index < 0x80000000U) {
        s.counters.dropped += index - s.depth_index - 1;
      }
      s.have_depth_index = true;
      s.depth_index = index;
    }
    if (type == openni::SENSOR_IR) {
      s.pending_ir.valid = s.take(type, s.frame_ref, s.pending_ir.image);
      s.pending_ir.stamp_ns = stamp;
      if (!s.pending_ir.valid) ++s.counters.corrupt;
      continue;
    }
    auto& own = type == openni::SENSOR_COLOR ? s.rgb_history : s.depth_history;
    auto& other = type == openni::SENSOR_COLOR ? s.depth_history : s.rgb_history;
    State::Pending& slot = s.slot_for_new(own);
    if (!s.take(type, s.frame_ref, slot.image)) {
      ++s.counters.corrupt;
      continue;
    }
    slot.valid = true;
    slot.stamp_ns = stamp;
    slot.index = static_cast<std::uint32_t>(s.frame_ref.getFrameIndex());
    State::Pending* partner = nullptr;
    for (auto& candidate : other) {
      if (candidate.valid && std::llabs(candidate.stamp_ns - stamp) <= gap_ns &&
          (partner == nullptr || std::llabs(candidate.stamp_ns - stamp) < std::llabs(partner->stamp_ns - stamp))) {
        partner = &candidate;
      }
    }
    if (partner == nullptr) continue;
    State::Pending& rgb = type == openni::SENSOR_COLOR ? slot : *partner;
    State::Pending& depth = type == openni::SENSOR_COLOR ? *partner : slot;
    std::swap(rgb.image, s.out_rgb);
    std::swap(depth.image, s.out_depth);
    rgb.valid = depth.valid = false;
    s.drop_older(s.rgb_history, rgb.stamp_ns);
    s.drop_older(s.depth_history, depth.stamp_ns);
    frame.ir.release();
    if (s.options.ir && s.pending_ir.valid && std::llabs(s.pending_ir.stamp_ns - depth.stamp_ns) <= gap_ns) {
      std::swap(s.pending_ir.image, s.out_ir);
      s.pending_ir.valid = false;
      frame.ir = s.out_ir;
    }
    s.last_stamp_ns = std::max(depth.stamp_ns, s.last_stamp_ns + 1);
    frame.sequence = depth.index;
    frame.stamp_ns = s.last_stamp_ns;
    frame.stamp_s = static_cast<double>(frame.stamp_ns) * 1e-9;
    frame.rgb = s.out_rgb;
    frame.depth = s.out_depth;
    ++s.counters.frames;
    return hal::ReadStatus::kOk;
  }
}

std::string OpenNI2Camera::describe() const {
  const State& s = *state_;
  const OpenNI2Stream& st = s.stream;
  const auto format = [](int code) { return format_name(static_cast<openni::PixelFormat>(code)); };
  std::string text = std::string("openni2 ") + (st.is_file ? "recording " : "device ") + st.uri + " (" + st.name +
                     "): " + std::to_string(st.width) + "x" + std::to_string(st.height) + "@" + std::to_string(st.fps) +
                     ", colour " + format(st.color_pixel_format) + ", depth " + format(st.depth_pixel_format);
  if (st.ir_pixel_format != 0) text += ", IR " + format(st.ir_pixel_format);
  text += st.registered ? ", registered depth-to-colour" : ", depth NOT registered to colour";
  text += st.synchronised ? ", frame sync on" : ", frame sync off (paired by stamp)";
  text += st.mirroring_off ? ", mirroring off" : ", mirroring unknown";
  if (st.is_file) text += ", " + std::to_string(st.recorded_frames) + " recorded depth frames";
  return text;
}

}  // namespace rankslam::openni2
