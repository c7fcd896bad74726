#include "rankslam/v4l2/v4l2_camera.hpp"

#include "rankslam/hal/reopen_wait.hpp"

#include "rankslam/v4l2/frame_conversion.hpp"

#include <opencv2/core.hpp>

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <utility>

namespace rankslam::v4l2 {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;
static_assert(V4l2Camera::kMaxBuffers >= 2, "streaming needs one buffer filling while one is read");

std::int64_t monotonic_ns() {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  return static_cast<std::int64_t>(now.tv_sec) * kNsPerS + now.tv_nsec;
}

int xioctl(int fd, unsigned long request, void* argument) {
  int result = 0;
  do {
    result = ::ioctl(fd, request, argument);
  } while (result < 0 && errno == EINTR);
  return result;
}

std::string text_of(const __u8* bytes, std::size_t size) {
  std::size_t length = 0;
  while (length < size && bytes[length] != 0) ++length;
  return {reinterpret_cast<const char*>(bytes), length};
}

bool is_mjpeg(std::uint32_t code) { return code == V4L2_PIX_FMT_MJPEG || code == V4L2_PIX_FMT_JPEG; }

}  // namespace

V4l2Camera::V4l2Camera(V4l2Options options) : options_(std::move(options)) {}

V4l2Camera::~V4l2Camera() { close(); }

std::string V4l2Camera::open() {
  close();
  if (options_.width <= 0 || options_.height <= 0 || options_.width % 2 != 0) {
    return "v4l2: image size " + std::to_string(options_.width) + "x" + std::to_string(options_.height) +
           " must be positive with an even width";
  }
  if (options_.buffer_count < 2 || options_.buffer_count > kMaxBuffers) {
    return "v4l2: buffer_count " + std::to_string(options_.buffer_count) + " must be within 2.." +
           std::to_string(kMaxBuffers);
  }
  counters_ = {};
  if (auto error = open_device(); !error.empty()) return error;
  opened_ = true;
  return {};
}

std::string V4l2Camera::open_device() {
  const std::string& path = options_.device;
  const int fd = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) return "v4l2: cannot open " + path + ": " + std::strerror(errno);
  fd_ = fd;
  const auto fail = [&](const std::string& what, bool with_errno) {
    const int error = errno;
    close_device();
    return "v4l2: " + path + ": " + what + (with_errno ? std::string(": ") + std::strerror(error) : std::string());
  };

  v4l2_capability capability{};
  if (xioctl(fd_, VIDIOC_QUERYCAP, &capability) < 0) return fail("not a V4L2 device (VIDIOC_QUERYCAP)", true);
  const std::uint32_t caps = (capability.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? capability.device_caps
                                                                                    : capability.capabilities;
  format_ = {};
  format_.driver = text_of(capability.driver, sizeof(capability.driver));
  format_.card = text_of(capability.card, sizeof(capability.card));
  format_.bus_info = text_of(capability.bus_info, sizeof(capability.bus_info));
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0) {
    if ((caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) != 0) return fail("multi-planar capture is not supported", false);
    return fail("'" + format_.card + "' is not a video capture device", false);
  }
  if ((caps & V4L2_CAP_STREAMING) == 0) return fail("'" + format_.card + "' cannot stream (no V4L2_CAP_STREAMING)", false);

  // What the device offers, for the choice and for a useful message.
  std::array<std::uint32_t, kMaxFormats> offered{};
  std::size_t offered_count = 0;
  for (std::uint32_t index = 0; offered_count < kMaxFormats; ++index) {
    v4l2_fmtdesc description{};
    description.index = index;
    description.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(fd_, VIDIOC_ENUM_FMT, &description) < 0) break;
    offered[offered_count++] = description.pixelformat;
  }
  const auto offers = [&](auto predicate) {
    for (std::size_t i = 0; i < offered_count; ++i) {
      if (predicate(offered[i])) return offered[i];
    }
    return std::uint32_t{0};
  };
  const std::uint32_t yuyv = offers([](std::uint32_t code) { return code == V4L2_PIX_FMT_YUYV; });
  const std::uint32_t mjpeg = offers(is_mjpeg);
  std::uint32_t chosen = 0;
  switch (options_.format) {
    case PixelFormat::kAuto: chosen = yuyv != 0 ? yuyv : mjpeg; break;
    case PixelFormat::kYuyv: chosen = yuyv; break;
    case PixelFormat::kMjpeg: chosen = mjpeg; break;
  }
  if (chosen == 0) {
    std::string list;
    for (std::size_t i = 0; i < offered_count; ++i) {
      if (i != 0) list += ' ';
      list += fourcc_to_string(offered[i]);
    }
    if (offered_count == kMaxFormats) list += " ...";
    const char* wanted = options_.format == PixelFormat::kYuyv    ? "YUYV"
                         : options_.format == PixelFormat::kMjpeg ? "MJPEG"
                                                                  : "YUYV or MJPEG";
    return fail(std::string("offers no ") + wanted + " (offers: " + (list.empty() ? "nothing" : list) + ")", false);
  }

  v4l2_format format{};
  format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  format.fmt.pix.width = static_cast<std::uint32_t>(options_.width);
  format.fmt.pix.height = static_cast<std::uint32_t>(options_.height);
  format.fmt.pix.pixelformat = chosen;
  format.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(fd_, VIDIOC_S_FMT, &format) < 0) return fail("VIDIOC_S_FMT " + fourcc_to_string(chosen), true);
  const auto& pix = format.fmt.pix;
  if (pix.pixelformat != chosen || static_cast<int>(pix.width) != options_.width ||
      static_cast<int>(pix.height) != options_.height) {
    return fail("asked for " + fourcc_to_string(chosen) + " " + std::to_string(options_.width) + "x" +
                    std::to_string(options_.height) + ", the device offers " + fourcc_to_string(pix.pixelformat) +
                    " " + std::to_string(pix.width) + "x" + std::to_string(pix.height),
                false);
  }
  if (pix.field != V4L2_FIELD_NONE && pix.field != V4L2_FIELD_ANY) {
    return fail("delivers interlaced fields (v4l2_field " + std::to_string(pix.field) + "); progressive needed", false);
  }
  format_.pixel_format = pix.pixelformat;
  format_.width = static_cast<int>(pix.width);
  format_.height = static_cast<int>(pix.height);
  format_.bytes_per_line = pix.bytesperline != 0 ? pix.bytesperline : pix.width * 2;
  format_.image_bytes = pix.sizeimage;

  v4l2_streamparm parameters{};
  parameters.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_G_PARM, &parameters) == 0) {
    if (options_.fps > 0 && (parameters.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0) {
      parameters.parm.capture.timeperframe = {.numerator = 1, .denominator = options_.fps};
      if (xioctl(fd_, VIDIOC_S_PARM, &parameters) < 0) return fail("VIDIOC_S_PARM", true);
    }
    format_.interval_numerator = parameters.parm.capture.timeperframe.numerator;
    format_.interval_denominator = parameters.parm.capture.timeperframe.denominator;
  }

  v4l2_requestbuffers request{};
  request.count = options_.buffer_count;
  request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  request.memory = V4L2_MEMORY_MMAP;
  if (xioctl(fd_, VIDIOC_REQBUFS, &request) < 0) return fail("memory-mapped streaming refused (VIDIOC_REQBUFS)", true);
  if (request.count < 2 || request.count > kMaxBuffers) {
    return fail("the device granted " + std::to_string(request.count) + " buffers, 2.." + std::to_string(kMaxBuffers) +
                    " needed",
                false);
  }
  for (std::uint32_t index = 0; index < request.count; ++index) {
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    buffer.index = index;
    if (xioctl(fd_, VIDIOC_QUERYBUF, &buffer) < 0) return fail("VIDIOC_QUERYBUF", true);
    void* data = ::mmap(nullptr, buffer.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buffer.m.offset);
    if (data == MAP_FAILED) return fail("mmap of buffer " + std::to_string(index), true);
    buffers_[index] = {.data = data, .length = buffer.length};
    mapped_count_ = index + 1;
    if (xioctl(fd_, VIDIOC_QBUF, &buffer) < 0) return fail("VIDIOC_QBUF", true);
  }
  format_.buffer_count = mapped_count_;

  try {
    image_.create(format_.height, format_.width, CV_8UC3);
  } catch (const cv::Exception& error) {
    return fail(std::string("cannot allocate the image: ") + error.what(), false);
  }
  v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(fd_, VIDIOC_STREAMON, &type) < 0) return fail("VIDIOC_STREAMON", true);
  streaming_ = true;
  have_sequence_ = false;
  return {};
}

void V4l2Camera::close_device() {
  if (fd_ >= 0 && streaming_) {
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    (void)xioctl(fd_, VIDIOC_STREAMOFF, &type);  // fails harmlessly on a vanished device
  }
  streaming_ = false;
  for (std::uint32_t index = 0; index < mapped_count_; ++index) {
    ::munmap(buffers_[index].data, buffers_[index].length);
    buffers_[index] = {};
  }
  mapped_count_ = 0;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void V4l2Camera::close() {
  close_device();
  opened_ = false;
}

bool V4l2Camera::ensure_open() {
  if (fd_ >= 0) return true;
  if (!opened_ || !options_.reopen_after_fault) return false;
  const std::int64_t now = monotonic_ns();
  const std::int64_t interval_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(options_.reopen_interval).count();
  if (last_reopen_attempt_ns_ != 0 && now - last_reopen_attempt_ns_ < interval_ns) return false;
  last_reopen_attempt_ns_ = now;
  if (!open_device().empty()) return false;
  ++counters_.reopens;
  return true;
}

bool V4l2Camera::wait_for_reopen(std::int64_t deadline_ns) {
  if (!opened_) return false;  // never opened or closed: waiting changes nothing
  return hal::sleep_until_reopen_due(last_reopen_attempt_ns_, options_.reopen_interval, options_.reopen_after_fault, deadline_ns) && ensure_open();
}

hal::ReadStatus V4l2Camera::fault() {
  close_device();
  ++counters_.faults;
  return hal::ReadStatus::kFault;
}

bool V4l2Camera::convert(std::uint32_t index, std::uint32_t bytes_used) {
  const auto* data = static_cast<const std::uint8_t*>(buffers_[index].data);
  const std::size_t size = std::min<std::size_t>(bytes_used, buffers_[index].length);
  if (is_mjpeg(format_.pixel_format)) return mjpeg_to_bgr(data, size, format_.width, format_.height, image_);
  return yuyv_to_bgr(data, size, format_.width, format_.height, format_.bytes_per_line, image_);
}

hal::ReadStatus V4l2Camera::read(hal::ImageFrame& frame, std::chrono::milliseconds wait) {
  const std::int64_t wait_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::max(wait, std::chrono::milliseconds{0})).count();
  const std::int64_t deadline_ns = monotonic_ns() + wait_ns;
  // A lasting fault waits out `wait` (or until a reopen is due) so that callers' read loops do not spin.
  if (!ensure_open() && !wait_for_reopen(deadline_ns)) {
    ++counters_.faults;
    return hal::ReadStatus::kFault;
  }
  for (;;) {
    v4l2_buffer buffer{};
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    if (xioctl(fd_, VIDIOC_DQBUF, &buffer) < 0) {
      if (errno != EAGAIN) return fault();  // ENODEV (unplugged), EIO (streaming error), ...
      const std::int64_t remaining_ns = deadline_ns - monotonic_ns();
      if (remaining_ns <= 0) {
        if (wait_ns == 0) return hal::ReadStatus::kNoData;
        ++counters_.timeouts;
        return hal::ReadStatus::kTimeout;
      }
      pollfd request{.fd = fd_, .events = POLLIN, .revents = 0};
      const timespec timeout{.tv_sec = remaining_ns / kNsPerS, .tv_nsec = remaining_ns % kNsPerS};
      const int ready = ::ppoll(&request, 1, &timeout, nullptr);
      if (ready < 0 && errno != EINTR) return fault();
      // POLLERR without a frame: the device stopped streaming or went away.
      if (ready > 0 && (request.revents & POLLIN) == 0 && (request.revents & (POLLERR | POLLHUP | POLLNVAL)) != 0) {
        return fault();
      }
      continue;
    }
    if (buffer.index >= mapped_count_) return fault();

    const bool usable = (buffer.flags & V4L2_BUF_FLAG_ERROR) == 0 && convert(buffer.index, buffer.bytesused);
    if (have_sequence_ && buffer.sequence != last_sequence_ + 1) {
      const std::uint32_t gap = buffer.sequence - last_sequence_ - 1;  // wraps like the sequence
      if (gap < 0x80000000U) counters_.dropped += gap;
    }
    have_sequence_ = true;
    last_sequence_ = buffer.sequence;
    const bool monotonic =
        (buffer.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    format_.monotonic_stamps = monotonic;
    const std::int64_t stamp_ns =
        monotonic ? static_cast<std::int64_t>(buffer.timestamp.tv_sec) * kNsPerS +
                        static_cast<std::int64_t>(buffer.timestamp.tv_usec) * 1000
                  : monotonic_ns();
    const std::uint32_t sequence = buffer.sequence;
    // The frame is in image_ now: hand the buffer straight back to the device (VIDIOC_QBUF
    // rewrites the struct, so everything needed is read before).
    if (xioctl(fd_, VIDIOC_QBUF, &buffer) < 0) return fault();
    if (!usable) {
      ++counters_.corrupt;
      continue;
    }
    if (!monotonic) ++counters_.unstamped;
    ++counters_.frames;
    frame.sequence = sequence;
    frame.stamp_ns = stamp_ns;
    frame.stamp_s = static_cast<double>(stamp_ns) * 1e-9;
    frame.image = image_;
    return hal::ReadStatus::kOk;
  }
}

std::string V4l2Camera::describe() const {
  char rate[32];
  std::snprintf(rate, sizeof(rate), "%.2f fps", format_.fps());
  return "v4l2 " + options_.device + ": " + format_.driver + " '" + format_.card + "' (" + format_.bus_info + "), " +
         fourcc_to_string(format_.pixel_format) + " " + std::to_string(format_.width) + "x" +
         std::to_string(format_.height) + ", " + (format_.fps() > 0.0 ? std::string(rate) : "device rate") + ", " +
         std::to_string(format_.buffer_count) + " buffers";
}

}  // namespace rankslam::v4l2
