// V4l2Camera against the kernel's vivid test-pattern capture driver (inside the VM).
//
// vivid is a real V4L2 driver with real videobuf2 streaming: format negotiation, frame
// intervals, mmap buffers, sequence numbers and monotonic stamps all come from the kernel.
// It offers no compressed formats, so the MJPEG path is checked here only for its refusal;
// the decoding itself is covered by the host unit tests (test/unit/v4l2). Device loss is
// provoked with vivid's "Disconnect" control, which makes the device behave as an unplugged
// USB camera (ENODEV, POLLERR|POLLHUP) until every handle is closed.

#include "allocation_counter.hpp"
#include "rankslam/v4l2/frame_conversion.hpp"
#include "rankslam/v4l2/v4l2_camera.hpp"
#include "vm_support.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

namespace rankslam::v4l2 {
namespace {

using namespace std::chrono_literals;
using hal::ReadStatus;

// An open device node, closed on scope exit.
struct DeviceHandle {
  explicit DeviceHandle(const std::string& path) : fd(::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC)) {}
  ~DeviceHandle() { reset(); }
  DeviceHandle(const DeviceHandle&) = delete;
  DeviceHandle& operator=(const DeviceHandle&) = delete;
  void reset() {
    if (fd >= 0) ::close(fd);
    fd = -1;
  }
  int fd;
};

std::string card_text(const __u8* text) { return reinterpret_cast<const char*>(text); }

// The first vivid node that captures video.
std::string find_vivid_capture() {
  for (int index = 0; index < 16; ++index) {
    const std::string path = "/dev/video" + std::to_string(index);
    DeviceHandle device(path);
    if (device.fd < 0) continue;
    v4l2_capability capability{};
    if (::ioctl(device.fd, VIDIOC_QUERYCAP, &capability) < 0) continue;
    const std::uint32_t caps = (capability.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? capability.device_caps
                                                                                      : capability.capabilities;
    if (card_text(capability.driver) == "vivid" && (caps & V4L2_CAP_VIDEO_CAPTURE) != 0) return path;
  }
  return {};
}

std::vector<std::uint32_t> capture_formats(int fd) {
  std::vector<std::uint32_t> formats;
  for (std::uint32_t index = 0;; ++index) {
    v4l2_fmtdesc description{};
    description.index = index;
    description.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (::ioctl(fd, VIDIOC_ENUM_FMT, &description) < 0) break;
    formats.push_back(description.pixelformat);
  }
  return formats;
}

// Id of the control called `name`.
std::optional<std::uint32_t> find_control(int fd, const std::string& name) {
  v4l2_queryctrl query{};
  query.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  while (::ioctl(fd, VIDIOC_QUERYCTRL, &query) == 0) {
    if (card_text(query.name) == name) return query.id;
    query.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  return std::nullopt;
}

bool set_control(int fd, std::uint32_t id, std::int32_t value) {
  v4l2_control control{};
  control.id = id;
  control.value = value;
  return ::ioctl(fd, VIDIOC_S_CTRL, &control) == 0;
}

bool press_button(int fd, std::uint32_t id) { return set_control(fd, id, 1); }

// Presses vivid's "Disconnect" through `control` (vivid stays unplugged while it is open) and
// reads until the camera stops delivering; the status that ended it goes to `status`.
void unplug(V4l2Camera& camera, hal::ImageFrame& frame, const DeviceHandle& control, ReadStatus& status) {
  ASSERT_GE(control.fd, 0);
  const auto disconnect = find_control(control.fd, "Disconnect");
  ASSERT_TRUE(disconnect.has_value()) << "vivid has no Disconnect control";
  ASSERT_TRUE(press_button(control.fd, *disconnect)) << std::strerror(errno);
  status = ReadStatus::kOk;
  for (int i = 0; i < 100 && status == ReadStatus::kOk; ++i) status = camera.read(frame, 1000ms);
}

// Busy and total jiffies of all CPUs (/proc/stat), to report how loaded the machine was.
std::pair<double, double> cpu_jiffies() {
  std::FILE* file = std::fopen("/proc/stat", "r");
  if (file == nullptr) return {0.0, 0.0};
  double user = 0, nice = 0, system = 0, idle = 0, iowait = 0, irq = 0, softirq = 0;
  const int fields = std::fscanf(file, "cpu %lf %lf %lf %lf %lf %lf %lf", &user, &nice, &system, &idle, &iowait, &irq, &softirq);
  std::fclose(file);
  if (fields != 7) return {0.0, 0.0};
  const double busy = user + nice + system + irq + softirq;
  return {busy, busy + idle + iowait};
}

class V4l2Vm : public ::testing::Test {
 protected:
  void SetUp() override {
    device_ = find_vivid_capture();
    RANKSLAM_VM_REQUIRE(!device_.empty(), "no vivid video capture device (/dev/video*)");
  }

  V4l2Options options(std::uint32_t fps = 30) const {
    V4l2Options result;
    result.device = device_;
    result.width = 640;
    result.height = 480;
    result.fps = fps;
    result.format = PixelFormat::kYuyv;
    result.reopen_interval = 0ms;
    return result;
  }

  std::string device_;
};

TEST(AllocationCounter, SeesAllocations) {
  test_support::CountAllocations count;
  std::vector<int> values(1000, 1);
  volatile int sink = values[999];
  (void)sink;
  EXPECT_GT(count.allocations(), 0);
}

TEST_F(V4l2Vm, DescribesTheDevice) {
  DeviceHandle device(device_);
  ASSERT_GE(device.fd, 0);
  std::string text;
  for (const auto format : capture_formats(device.fd)) text += " " + fourcc_to_string(format);
  std::printf("%s capture formats:%s\n", device_.c_str(), text.c_str());
  text.clear();
  for (std::uint32_t index = 0;; ++index) {
    v4l2_frmsizeenum size{};
    size.index = index;
    size.pixel_format = V4L2_PIX_FMT_YUYV;
    if (::ioctl(device.fd, VIDIOC_ENUM_FRAMESIZES, &size) < 0 || size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
    text += " " + std::to_string(size.discrete.width) + "x" + std::to_string(size.discrete.height);
  }
  std::printf("YUYV sizes:%s\n", text.c_str());
  text.clear();
  for (std::uint32_t index = 0;; ++index) {
    v4l2_frmivalenum interval{};
    interval.index = index;
    interval.pixel_format = V4L2_PIX_FMT_YUYV;
    interval.width = 640;
    interval.height = 480;
    if (::ioctl(device.fd, VIDIOC_ENUM_FRAMEINTERVALS, &interval) < 0 ||
        interval.type != V4L2_FRMIVAL_TYPE_DISCRETE) {
      break;
    }
    text += " " + std::to_string(interval.discrete.numerator) + "/" + std::to_string(interval.discrete.denominator);
  }
  std::printf("YUYV 640x480 frame intervals (s):%s\n", text.c_str());
  EXPECT_FALSE(text.empty());
  text.clear();
  v4l2_queryctrl query{};
  query.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  while (::ioctl(device.fd, VIDIOC_QUERYCTRL, &query) == 0) {
    if (query.type != V4L2_CTRL_TYPE_CTRL_CLASS) text += " '" + card_text(query.name) + "'";
    query.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  std::printf("controls:%s\n", text.c_str());
}

TEST_F(V4l2Vm, NegotiatesYuyv640x480AtTheRequestedRate) {
  V4l2Camera slow(options(15));
  ASSERT_EQ(slow.open(), "");
  EXPECT_DOUBLE_EQ(slow.negotiated().fps(), 15.0);
  slow.close();

  // vivid's fastest rate at 640x480 is 25 fps: a request for 30 gets that, and says so.
  V4l2Camera camera(options(30));
  ASSERT_EQ(camera.open(), "");
  std::printf("%s\n", camera.describe().c_str());
  const auto& format = camera.negotiated();
  EXPECT_EQ(format.driver, "vivid");
  EXPECT_EQ(format.pixel_format, V4L2_PIX_FMT_YUYV);
  EXPECT_EQ(format.width, 640);
  EXPECT_EQ(format.height, 480);
  EXPECT_GE(format.bytes_per_line, 640U * 2);
  EXPECT_DOUBLE_EQ(format.fps(), 25.0);
  EXPECT_EQ(format.buffer_count, 4U);
  EXPECT_TRUE(camera.is_open());
}

TEST_F(V4l2Vm, OpenExplainsWhatTheDeviceCannotDo) {
  V4l2Options missing = options();
  missing.device = "/dev/video99";
  V4l2Camera absent(missing);
  const std::string absent_error = absent.open();
  EXPECT_NE(absent_error.find("/dev/video99"), std::string::npos) << absent_error;

  V4l2Options odd = options();
  odd.width = 1000;
  odd.height = 1000;
  V4l2Camera odd_camera(odd);
  const std::string size_error = odd_camera.open();
  EXPECT_NE(size_error.find("1000x1000"), std::string::npos) << size_error;
  EXPECT_FALSE(odd_camera.is_open());
  std::printf("odd size: %s\n", size_error.c_str());
}

TEST_F(V4l2Vm, MjpegIsDecodedWhenOfferedAndRefusedClearlyOtherwise) {
  DeviceHandle device(device_);
  ASSERT_GE(device.fd, 0);
  const auto formats = capture_formats(device.fd);
  device.reset();
  const bool offers_mjpeg = std::any_of(formats.begin(), formats.end(), [](std::uint32_t code) {
    return code == V4L2_PIX_FMT_MJPEG || code == V4L2_PIX_FMT_JPEG;
  });
  V4l2Options mjpeg = options();
  mjpeg.format = PixelFormat::kMjpeg;
  V4l2Camera camera(mjpeg);
  const std::string error = camera.open();
  if (offers_mjpeg) {
    ASSERT_EQ(error, "");
    hal::ImageFrame frame;
    ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);
    EXPECT_EQ(frame.image.cols, 640);
    EXPECT_EQ(frame.image.type(), CV_8UC3);
  } else {
    std::printf("the device offers no MJPEG: %s\n", error.c_str());
    EXPECT_NE(error.find("offers no MJPEG"), std::string::npos) << error;
    EXPECT_NE(error.find("YUYV"), std::string::npos) << error;  // the list of what it offers
  }
}

// Frames delivered in one window of the guest's monotonic clock, and what came with them.
struct CaptureWindow {
  int delivered = 0;
  /// Frames the device produced in the window: the span of the delivered frames' sequence numbers.
  std::uint64_t produced = 0;
  int timeouts = 0;
  int stamp_reversals = 0;
  int sequence_reversals = 0;
  std::uint64_t device_gaps = 0;
  double mean_interval_ms = 0.0;
  double stamp_span_s = 0.0;
  double cpu_busy_percent = 0.0;
  ReadStatus failure = ReadStatus::kOk;  ///< A status other than ok/timeout that ended it early.
};

CaptureWindow capture_window(V4l2Camera& camera, hal::ImageFrame& frame, std::chrono::milliseconds window) {
  // Take what queued before, so the window counts frames captured inside it.
  while (camera.read(frame, 0ms) == ReadStatus::kOk) {
  }
  CaptureWindow result;
  const std::uint64_t gaps_before = camera.counters().dropped;
  std::int64_t last_stamp_ns = frame.stamp_ns;
  std::uint32_t last_sequence = frame.sequence;
  const std::uint32_t first_sequence = frame.sequence;
  const std::int64_t first_stamp_ns = frame.stamp_ns;
  double interval_sum_ms = 0.0;
  const auto cpu_before = cpu_jiffies();
  const auto start = std::chrono::steady_clock::now();
  for (auto now = start; now - start < window; now = std::chrono::steady_clock::now()) {
    const auto remaining = std::chrono::duration_cast<std::chrono::milliseconds>(window - (now - start));
    const ReadStatus status = camera.read(frame, std::min<std::chrono::milliseconds>(remaining, 500ms));
    if (status == ReadStatus::kTimeout || status == ReadStatus::kNoData) {  // kNoData: window ended
      result.timeouts += status == ReadStatus::kTimeout ? 1 : 0;
      continue;
    }
    if (status != ReadStatus::kOk) {
      result.failure = status;
      break;
    }
    ++result.delivered;
    result.stamp_reversals += frame.stamp_ns < last_stamp_ns ? 1 : 0;
    result.sequence_reversals += frame.sequence < last_sequence ? 1 : 0;
    interval_sum_ms += static_cast<double>(frame.stamp_ns - last_stamp_ns) * 1e-6;
    last_stamp_ns = frame.stamp_ns;
    last_sequence = frame.sequence;
  }
  const auto cpu_after = cpu_jiffies();
  result.device_gaps = camera.counters().dropped - gaps_before;
  result.produced = last_sequence - first_sequence;
  result.mean_interval_ms = result.delivered > 0 ? interval_sum_ms / result.delivered : 0.0;
  result.stamp_span_s = static_cast<double>(last_stamp_ns - first_stamp_ns) * 1e-9;
  result.cpu_busy_percent =
      100.0 * (cpu_after.first - cpu_before.first) / std::max(1.0, cpu_after.second - cpu_before.second);
  return result;
}

TEST_F(V4l2Vm, DeliversAtLeast95PercentOfTheFramesTheDeviceProducesOver5Seconds) {
  V4l2Camera camera(options(25));  // vivid's fastest rate at 640x480
  ASSERT_EQ(camera.open(), "");
  const double fps = camera.negotiated().fps();
  ASSERT_GT(fps, 0.0);
  std::printf("%s\n", camera.describe().c_str());
  hal::ImageFrame frame;
  // Warm up for a second: the first conversion initialises OpenCV, slow on an emulated CPU,
  // while the device runs on and skips frames.
  const auto warm_up_end = std::chrono::steady_clock::now() + 1s;
  while (std::chrono::steady_clock::now() < warm_up_end) ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);

  // What the driver controls is measured against what the device produced (its sequence
  // numbers): every frame delivered or counted as skipped, and at least 95 % delivered. How many
  // vivid produces in 5 s of the guest's clock is the emulator's business, only reported. A
  // burst of work on the host can stall the whole VM for a moment, so a short window gets one
  // more; a driver that loses frames loses them in every window.
  constexpr auto kWindow = 5000ms;
  const double nominal = fps * std::chrono::duration<double>(kWindow).count();
  double best_ratio = 0.0;
  for (int attempt = 1; attempt <= 2 && best_ratio < 0.95; ++attempt) {
    const CaptureWindow window = capture_window(camera, frame, kWindow);
    ASSERT_EQ(window.failure, ReadStatus::kOk) << hal::to_string(window.failure);
    ASSERT_GT(window.produced, 0U);
    const double ratio = window.delivered / static_cast<double>(window.produced);
    best_ratio = std::max(best_ratio, ratio);
    std::printf("window %d: delivered %d of the %llu frames the device produced (%.1f %%), skipped by the device %llu; "
                "%.1f %% of the nominal %.0f in 5 s; timeouts %d; mean stamp interval %.2f ms (nominal %.2f ms), "
                "stamps span %.3f s; guest CPU busy %.0f %%\n",
                attempt, window.delivered, static_cast<unsigned long long>(window.produced), 100.0 * ratio,
                static_cast<unsigned long long>(window.device_gaps), 100.0 * window.delivered / nominal, nominal,
                window.timeouts, window.mean_interval_ms, 1e3 / fps, window.stamp_span_s, window.cpu_busy_percent);
    EXPECT_EQ(window.produced, static_cast<std::uint64_t>(window.delivered) + window.device_gaps)
        << "a frame was neither delivered nor counted as skipped";
    EXPECT_EQ(window.stamp_reversals, 0);
    EXPECT_EQ(window.sequence_reversals, 0);
  }
  EXPECT_GE(best_ratio, 0.95);
  EXPECT_TRUE(camera.negotiated().monotonic_stamps);
  EXPECT_EQ(camera.counters().unstamped, 0U);
  EXPECT_EQ(camera.counters().corrupt, 0U);

  // The picture is vivid's default 75 % colour bars, eight bars of 80 pixels; below the text
  // block every bar must have its colour in BGR order, which checks the YUYV conversion.
  ASSERT_EQ(frame.image.rows, 480);
  ASSERT_EQ(frame.image.cols, 640);
  ASSERT_EQ(frame.image.type(), CV_8UC3);
  const std::array<cv::Vec3b, 8> bars{{{191, 191, 191}, {0, 191, 191}, {191, 191, 0}, {0, 191, 0},
                                       {191, 0, 191}, {0, 0, 191}, {191, 0, 0}, {0, 0, 0}}};
  for (int bar = 0; bar < 8; ++bar) {
    const cv::Vec3b pixel = frame.image.at<cv::Vec3b>(400, 40 + 80 * bar);
    for (int channel = 0; channel < 3; ++channel) {
      EXPECT_NEAR(pixel[channel], bars[static_cast<std::size_t>(bar)][channel], 24)
          << "bar " << bar << " channel " << channel;
    }
  }
  if (const auto dir = vm_test::output_dir(); !dir.empty()) cv::imwrite(dir + "/vivid-640x480.png", frame.image);
}

TEST_F(V4l2Vm, ReadsTimeOutWhenNoFrameIsDue) {
  V4l2Camera camera(options(1));  // one frame a second
  ASSERT_EQ(camera.open(), "");
  const double fps = camera.negotiated().fps();
  ASSERT_GT(fps, 0.0);
  ASSERT_LE(fps, 5.0) << camera.describe();
  const auto interval = std::chrono::milliseconds(static_cast<int>(1000.0 / fps));
  hal::ImageFrame frame;
  ASSERT_EQ(camera.read(frame, interval * 3), ReadStatus::kOk);
  // A frame has just arrived; the next is an interval away.
  EXPECT_EQ(camera.read(frame, 0ms), ReadStatus::kNoData);
  EXPECT_EQ(camera.read(frame, interval / 4), ReadStatus::kTimeout);
  EXPECT_EQ(camera.counters().timeouts, 1U);
  ASSERT_EQ(camera.read(frame, interval * 3), ReadStatus::kOk);
  EXPECT_EQ(camera.counters().frames, 2U);
}

TEST_F(V4l2Vm, DisconnectIsAFaultAndTheCameraReopensOnReconnect) {
  V4l2Camera camera(options());
  ASSERT_EQ(camera.open(), "");
  hal::ImageFrame frame;
  ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);

  // The camera sees an unplugged device: a fault, not a crash, and no hang.
  DeviceHandle control(device_);
  ReadStatus status = ReadStatus::kOk;
  ASSERT_NO_FATAL_FAILURE(unplug(camera, frame, control, status));
  EXPECT_EQ(status, ReadStatus::kFault);
  EXPECT_FALSE(camera.is_open());
  EXPECT_EQ(camera.counters().faults, 1U);
  std::printf("after disconnect: %s, reopen attempt: %s\n", hal::to_string(status).data(),
              hal::to_string(camera.read(frame, 100ms)).data());

  // vivid reconnects once its last handle closes; the camera then reopens by itself.
  control.reset();
  status = camera.read(frame, 3000ms);
  EXPECT_EQ(status, ReadStatus::kOk) << hal::to_string(status);
  EXPECT_TRUE(camera.is_open());
  EXPECT_EQ(camera.counters().reopens, 1U);
  EXPECT_EQ(frame.image.cols, 640);
}

TEST_F(V4l2Vm, WhileUnpluggedReadsSleepInsteadOfSpinning) {
  // 0 ms: a reopen at every read; 400 ms: some reads wake early for a due reopen attempt.
  for (const auto interval : {0ms, 400ms}) {
    SCOPED_TRACE("reopen_interval " + std::to_string(interval.count()) + " ms");
    V4l2Options unplugged = options();
    unplugged.reopen_interval = interval;
    V4l2Camera camera(unplugged);
    ASSERT_EQ(camera.open(), "");
    hal::ImageFrame frame;
    ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);
    DeviceHandle control(device_);
    ReadStatus status = ReadStatus::kOk;
    ASSERT_NO_FATAL_FAILURE(unplug(camera, frame, control, status));
    ASSERT_EQ(status, ReadStatus::kFault);

    // vivid stays unplugged while `control` is open: every reopen fails. Each read sleeps until
    // its wait ends or a reopen attempt is due: ~8-13 in 2 s; a read returning at once: thousands.
    int reads = 0;
    const auto end = std::chrono::steady_clock::now() + 2s;
    while (std::chrono::steady_clock::now() < end) {
      EXPECT_EQ(camera.read(frame, 250ms), ReadStatus::kFault) << "read " << reads;
      ++reads;
    }
    std::printf("reopen_interval %lld ms: %d reads of 250 ms in 2 s while unplugged\n",
                static_cast<long long>(interval.count()), reads);
    EXPECT_LE(reads, 40);
    EXPECT_GE(reads, 2);
    EXPECT_EQ(camera.counters().faults, 1U + static_cast<std::uint64_t>(reads));
    EXPECT_EQ(camera.counters().reopens, 0U);
    // A zero wait still returns at once.
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(camera.read(frame, 0ms), ReadStatus::kFault);
    EXPECT_LT(std::chrono::steady_clock::now() - start, 250ms);

    // Plugged back: a read waiting for the due reopen attempt gets a frame.
    control.reset();
    status = ReadStatus::kFault;
    for (int i = 0; i < 5 && status != ReadStatus::kOk; ++i) status = camera.read(frame, 3000ms);
    EXPECT_EQ(status, ReadStatus::kOk) << hal::to_string(status);
    EXPECT_EQ(camera.counters().reopens, 1U);
  }
}

TEST_F(V4l2Vm, SteadyStateCaptureAllocatesNothing) {
  V4l2Camera camera(options(25));
  ASSERT_EQ(camera.open(), "");
  hal::ImageFrame frame;
  const auto warm_up_end = std::chrono::steady_clock::now() + 500ms;
  while (std::chrono::steady_clock::now() < warm_up_end) ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);

  constexpr std::size_t kReads = 25;
  std::array<ReadStatus, kReads> statuses{};
  long allocations = 0;
  {
    test_support::CountAllocations count;
    for (auto& status : statuses) status = camera.read(frame, 1000ms);
    allocations = count.allocations();
  }
  EXPECT_EQ(allocations, 0) << "heap allocations in " << kReads << " steady-state reads";
  EXPECT_EQ(std::count(statuses.begin(), statuses.end(), ReadStatus::kOk), static_cast<long>(kReads));
}

TEST_F(V4l2Vm, BuffersFlaggedInErrorAreSkippedAndCounted) {
  V4l2Camera camera(options(25));
  ASSERT_EQ(camera.open(), "");
  hal::ImageFrame frame;
  ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);
  DeviceHandle control(device_);
  const auto inject = find_control(control.fd, "Inject V4L2_BUF_FLAG_ERROR");
  ASSERT_TRUE(inject.has_value());
  // vivid flags the next buffer it fills; a tick with no queued buffer flags none, so retry.
  int presses = 0;
  while (camera.counters().corrupt == 0 && presses < 3) {
    ASSERT_TRUE(press_button(control.fd, *inject)) << std::strerror(errno);
    ++presses;
    for (int i = 0; i < 12; ++i) ASSERT_EQ(camera.read(frame, 1000ms), ReadStatus::kOk);
  }
  EXPECT_GE(camera.counters().corrupt, 1U);
  EXPECT_LE(camera.counters().corrupt, static_cast<std::uint64_t>(presses));
  EXPECT_TRUE(camera.is_open());
  EXPECT_EQ(frame.image.cols, 640);
}

TEST_F(V4l2Vm, FramesTheDeviceDropsAreCounted) {
  DeviceHandle control(device_);
  const auto percentage = find_control(control.fd, "Percentage of Dropped Buffers");
  ASSERT_TRUE(percentage.has_value());
  ASSERT_TRUE(set_control(control.fd, *percentage, 50)) << std::strerror(errno);
  struct Restore {
    int fd;
    std::uint32_t id;
    ~Restore() { (void)set_control(fd, id, 0); }
  } restore{control.fd, *percentage};

  V4l2Camera camera(options(25));
  ASSERT_EQ(camera.open(), "");
  hal::ImageFrame frame;
  const auto end = std::chrono::steady_clock::now() + 2s;
  while (std::chrono::steady_clock::now() < end) {
    const ReadStatus status = camera.read(frame, 1000ms);
    ASSERT_TRUE(status == ReadStatus::kOk || status == ReadStatus::kTimeout) << hal::to_string(status);
  }
  const auto& counters = camera.counters();
  std::printf("with half the buffers dropped by the device: %llu frames, %llu counted as dropped\n",
              static_cast<unsigned long long>(counters.frames), static_cast<unsigned long long>(counters.dropped));
  EXPECT_GE(counters.frames, 10U);
  EXPECT_GE(counters.dropped, 10U);
}

TEST_F(V4l2Vm, AFatalStreamingErrorIsAFaultAndTheCameraRecovers) {
  V4l2Camera camera(options(25));
  ASSERT_EQ(camera.open(), "");
  hal::ImageFrame frame;
  ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);
  DeviceHandle control(device_);
  const auto fatal = find_control(control.fd, "Inject Fatal Streaming Error");
  ASSERT_TRUE(fatal.has_value());
  ASSERT_TRUE(press_button(control.fd, *fatal)) << std::strerror(errno);

  ReadStatus status = ReadStatus::kOk;
  for (int i = 0; i < 50 && status == ReadStatus::kOk; ++i) status = camera.read(frame, 1000ms);
  EXPECT_EQ(status, ReadStatus::kFault);
  EXPECT_EQ(camera.counters().faults, 1U);
  // Reopening restarts streaming: frames flow again.
  status = camera.read(frame, 3000ms);
  EXPECT_EQ(status, ReadStatus::kOk) << hal::to_string(status);
  EXPECT_EQ(camera.counters().reopens, 1U);
}

// Runs last: it tries to unload the driver under an open camera.
TEST_F(V4l2Vm, UnloadingTheDriverUnderAnOpenCameraIsRefused) {
  V4l2Camera camera(options());
  ASSERT_EQ(camera.open(), "");
  hal::ImageFrame frame;
  ASSERT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);
  const int unload = vm_test::shell("busybox rmmod vivid");
  std::printf("rmmod vivid with the device open: exit %d\n", unload);
  if (unload == 0) {
    // The kernel let the driver go: the camera must report it, not crash.
    EXPECT_EQ(camera.read(frame, 1000ms), ReadStatus::kFault);
  } else {
    // The open file pins the module: streaming goes on untouched.
    EXPECT_EQ(camera.read(frame, 3000ms), ReadStatus::kOk);
  }
}

}  // namespace
}  // namespace rankslam::v4l2
