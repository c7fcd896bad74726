#include "rankslam/sim/simulator.hpp"

#include "renderer.hpp"
#include "wheel_log.hpp"

#include "rankslam/hal/atomic_file.hpp"
#include "rankslam/sim/scene.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>
#include <numbers>
#include <thread>

namespace rankslam::sim {
namespace {

namespace fs = std::filesystem;

constexpr std::int64_t kStartStamp_us = 1'700'000'000'000'000;
constexpr int kFrameRate_hz = 30;
constexpr int kFisheyeDivider = 3;  // fisheye at 10 Hz
constexpr int kMaxFrames = 1'000'000;

struct SceneInfo {
  const char* name;
  const char* description;
};

constexpr std::array<SceneInfo, 5> kScenes = {{
    {"office",
     "Textured office room (5 x 4 m: painted walls with posters and a whiteboard, carpet, two desks with a "
     "monitor, keyboard and books, a chair, a cabinet, cardboard boxes) seen by a hand-held RGB-D camera moving "
     "smoothly in 6 DoF like TUM fr1_desk (about 0.4 m/s and 25 deg/s). 300 frames (a 10 s loop)."},
    {"zigzag-plain",
     "Eight untextured panels folded in a zig-zag on the floor of a plain room: uniform albedo, only shading, like "
     "TUM fr3 structure_notexture. The camera sweeps along the panels. Photometric features fail here, geometric "
     "ones work. 300 frames."},
    {"poster-wall",
     "A single plane covered with posters, stickers and painted marks and nothing else, like TUM fr3 "
     "nostructure_texture: geometric features fail, photometric ones work. 300 frames."},
    {"dark-office",
     "The office with the lights off: colour images almost black (mean below 15) and dominated by sensor noise. "
     "ir/ holds the Kinect IR images: IR reflectance lit by the projector, with its speckle dots, which shift with "
     "depth as seen from the projector 7.5 cm beside the camera. 300 frames."},
    {"corridor-loop",
     "A rectangular corridor loop (6 x 4 m centre line, 1.6 m wide) with plain walls, door recesses, pillars, "
     "boxes and a bench, driven by a differential-drive robot at 0.3 m/s back to its start; it turns in place at "
     "the corners and once stops facing a blank wall. Colour camera 0.5 m above the floor. Adds can.log (wheel "
     "encoders at 100 Hz with tick noise and wheel slip, slip.txt lists the slips) and a 190 deg fisheye camera "
     "at 10 Hz. About 2800 frames (one loop)."},
}};

// "1700000000.033333" for a stamp in microseconds.
void format_stamp(std::int64_t stamp_us, char (&out)[32]) {
  std::snprintf(out, sizeof out, "%" PRId64 ".%06" PRId64, stamp_us / 1'000'000, stamp_us % 1'000'000);
}

std::int64_t frame_stamp_us(std::int64_t frame) {
  return kStartStamp_us + (frame * 1'000'000 + kFrameRate_hz / 2) / kFrameRate_hz;
}

// Shortest text that reads back as the same double.
std::string number(double value) {
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, value);
  std::string text(buffer, result.ptr);
  if (text.find_first_of(".e") == std::string::npos && text.find("inf") == std::string::npos &&
      text.find("nan") == std::string::npos) {
    text += ".0";
  }
  return text;
}

std::string list(std::initializer_list<double> values) {
  std::string text = "[";
  bool first = true;
  for (const double v : values) {
    if (!first) text += ", ";
    text += number(v);
    first = false;
  }
  return text + "]";
}

Eigen::Quaterniond canonical_quaternion(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  return q;
}

std::string camera_yaml(const char* name, const hal::CameraCalibration& camera, const char* comment) {
  std::string text = std::string("  ") + name + ":  # " + comment + "\n";
  const bool fisheye = camera.model == hal::CameraModel::kFisheye;
  text += std::string("    model: ") + (fisheye ? "fisheye" : "pinhole") + "\n";
  text += "    width: " + std::to_string(camera.width) + "\n";
  text += "    height: " + std::to_string(camera.height) + "\n";
  text += "    intrinsics: " + list({camera.fx, camera.fy, camera.cx, camera.cy}) + "  # fx fy cx cy\n";
  const auto& d = camera.distortion;
  if (fisheye) {
    text += "    distortion: " + list({d[0], d[1], d[2], d[3]}) + "  # k1 k2 k3 k4 (OpenCV fisheye)\n";
  } else {
    text += "    distortion: " + list({d[0], d[1], d[2], d[3], d[4]}) + "  # k1 k2 p1 p2 k3\n";
  }
  const Eigen::Vector3d t = camera.T_base_cam.translation();
  const Eigen::Quaterniond q = canonical_quaternion(camera.T_base_cam.linear());
  text += "    T_base_cam:  # camera optical frame (x right, y down, z forward) -> base (x forward, y left, z up)\n";
  text += "      translation: " + list({t.x(), t.y(), t.z()}) + "\n";
  text += "      rotation_xyzw: " + list({q.x(), q.y(), q.z(), q.w()}) + "\n";
  return text;
}

// The first line of a simulated recording's calibration.yaml, which names its scene.
std::string calibration_header(const std::string& scene) {
  return "# rankslam recording calibration: simulated scene '" + scene + "'";
}

std::string calibration_yaml(const SceneModel& scene) {
  const hal::Calibration& c = scene.calibration;
  std::string text = calibration_header(scene.name) + "\n";
  text += "depth_scale: " + number(c.depth_scale) + "  # raw depth units per metre\n";
  text += "depth_noise_per_m: " + number(c.depth_noise_per_m) + "  # a in the axial depth noise a*z^2\n";
  text += "cameras:\n";
  text += camera_yaml("rgb", c.rgb, "colour camera; depth and IR images are registered to it");
  if (c.fisheye) {
    text += camera_yaml("fisheye", *c.fisheye, "wide-angle camera, equidistant model");
    text += "    field_of_view_deg: 190.0  # image circle: 95 deg from the optical axis\n";
  }
  if (c.wheels) {
    char id[32];
    std::snprintf(id, sizeof id, "0x%X", c.wheels->can_id);
    text += "wheels:  # differential drive, encoder frames in can.log\n";
    text += "  radius_m: " + number(c.wheels->radius_m) + "\n";
    text += "  track_width_m: " + number(c.wheels->track_width_m) + "\n";
    text += "  ticks_per_revolution: " + std::to_string(c.wheels->ticks_per_revolution) + "\n";
    text += std::string("  can_id: ") + id + "\n";
  }
  return text;
}

std::string write_bytes(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return "cannot create " + path + ": " + std::strerror(errno);
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string error = "cannot write " + path + ": " + std::strerror(errno);
      ::close(fd);
      return error;
    }
    written += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) return "cannot write " + path + ": " + std::strerror(errno);
  return {};
}

// Fixed worker threads; run() hands out task indices until all are done. The calling thread
// works too. Which thread runs a task never changes its result.
class WorkerPool {
 public:
  class Job {
   public:
    virtual ~Job() = default;
    virtual void execute(int task, int thread) = 0;
  };

  explicit WorkerPool(int threads) {
    for (int i = 1; i < threads; ++i) workers_.emplace_back([this, i] { work(i); });
  }
  ~WorkerPool() {
    {
      const std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (auto& worker : workers_) worker.join();
  }
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  void run(Job& job, int count) {
    {
      const std::lock_guard lock(mutex_);
      job_ = &job;
      count_ = count;
      next_.store(0);
      finished_ = 0;
      ++generation_;
    }
    wake_.notify_all();
    for (int i = next_.fetch_add(1); i < count; i = next_.fetch_add(1)) job.execute(i, 0);
    std::unique_lock lock(mutex_);
    done_.wait(lock, [&] { return finished_ == static_cast<int>(workers_.size()); });
  }

 private:
  void work(int thread) {
    std::uint64_t seen = 0;
    for (;;) {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      Job* job = job_;
      const int count = count_;
      lock.unlock();
      for (int i = next_.fetch_add(1); i < count; i = next_.fetch_add(1)) job->execute(i, thread);
      lock.lock();
      if (++finished_ == static_cast<int>(workers_.size())) done_.notify_one();
    }
  }

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  Job* job_ = nullptr;
  int count_ = 0;
  std::atomic<int> next_{0};
  int finished_ = 0;
  std::uint64_t generation_ = 0;
  bool stop_ = false;
};

enum Stream : int { kRgb = 0, kDepth = 1, kIr = 2, kFisheye = 3, kStreamCount = 4 };
constexpr std::array<const char*, kStreamCount> kStreamFolders = {"rgb", "depth", "ir", "fisheye"};

// Renders and writes the images, two frames in flight: while the bands of frame i render,
// frame i − 1 is PNG-encoded and written.
class ImagePipeline final : public WorkerPool::Job {
 public:
  ImagePipeline(const SceneModel& scene, const SimulationOptions& options, int threads, const fs::path& out_dir)
      : scene_(scene),
        options_(options),
        renderer_(scene, {options.seed, options.sensor_noise, options.min_depth_m, options.max_depth_m, threads}),
        pool_(threads) {
    samples_ = options.motion_blur ? options.motion_blur_samples : 1;
    // Default: OpenCV's speed setting (zlib level 1, one row filter) with Huffman-only coding;
    // sensor noise leaves little for string matching to find, so this is both faster and
    // about as small.
    png_params_ = options.png_compression_level >= 0
                      ? std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, options.png_compression_level}
                      : std::vector<int>{cv::IMWRITE_PNG_STRATEGY, cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY};
    const auto& rgb = scene.calibration.rgb;
    const detail::CameraRays* fisheye = renderer_.fisheye_rays();
    int max_width = rgb.width;
    if (fisheye) max_width = std::max(max_width, fisheye->width);
    for (int t = 0; t < threads; ++t) workspaces_.emplace_back(max_width, renderer_.quad_count());
    for (auto& slot : slots_) {
      slot.images.rgb.create(rgb.height, rgb.width, CV_8UC3);
      slot.images.depth.create(rgb.height, rgb.width, CV_16UC1);
      if (scene.has_ir) slot.images.ir.create(rgb.height, rgb.width, CV_8UC1);
      if (fisheye) slot.fisheye.create(fisheye->height, fisheye->width, CV_8UC3);
      slot.rgb_views.resize(static_cast<std::size_t>(samples_));
      slot.fisheye_views.resize(static_cast<std::size_t>(samples_));
      for (auto& view : slot.rgb_views) view.quads.reserve(renderer_.quad_count());
      for (auto& view : slot.fisheye_views) view.quads.reserve(renderer_.quad_count());
      for (int s = 0; s < kStreamCount; ++s) {
        auto& path = slot.paths[static_cast<std::size_t>(s)];
        path.reserve(out_dir.string().size() + 64);
        slot.bases[static_cast<std::size_t>(s)] = (out_dir / kStreamFolders[static_cast<std::size_t>(s)]).string() + "/";
      }
    }
    rgb_bands_ = (rgb.height + detail::CameraRays::kTile - 1) / detail::CameraRays::kTile;
    fisheye_bands_ = fisheye ? (fisheye->height + detail::CameraRays::kTile - 1) / detail::CameraRays::kTile : 0;
    tasks_.reserve(static_cast<std::size_t>(kStreamCount + rgb_bands_ + fisheye_bands_));
  }

  // Frames [first, first + frames) of the scene's timeline.
  std::string run(int first, int frames) {
    for (int i = 0; i <= frames; ++i) {
      tasks_.clear();
      if (i > 0) {
        Slot& previous = slots_[static_cast<std::size_t>((i - 1) % 2)];
        if (previous.has_fisheye) tasks_.push_back({Task::kEncode, (i - 1) % 2, kFisheye});
        tasks_.push_back({Task::kEncode, (i - 1) % 2, kRgb});
        tasks_.push_back({Task::kEncode, (i - 1) % 2, kDepth});
        if (scene_.has_ir) tasks_.push_back({Task::kEncode, (i - 1) % 2, kIr});
      }
      if (i < frames) {
        const int s = i % 2;
        prepare(first + i, slots_[static_cast<std::size_t>(s)]);
        if (slots_[static_cast<std::size_t>(s)].has_fisheye) {
          for (int b = 0; b < fisheye_bands_; ++b) tasks_.push_back({Task::kFisheyeBand, s, b});
        }
        for (int b = 0; b < rgb_bands_; ++b) tasks_.push_back({Task::kRgbdBand, s, b});
      }
      pool_.run(*this, static_cast<int>(tasks_.size()));
      for (auto& slot : slots_) {
        for (auto& error : slot.errors) {
          if (!error.empty()) return error;
        }
      }
    }
    return {};
  }

  void execute(int task_index, int thread) override {
    const Task& task = tasks_[static_cast<std::size_t>(task_index)];
    Slot& slot = slots_[static_cast<std::size_t>(task.slot)];
    detail::BandWorkspace& ws = workspaces_[static_cast<std::size_t>(thread)];
    switch (task.kind) {
      case Task::kRgbdBand:
        renderer_.render_rgbd_band(slot.rgb_views, task.index, static_cast<std::uint64_t>(slot.frame), slot.images, ws);
        break;
      case Task::kFisheyeBand:
        renderer_.render_fisheye_band(slot.fisheye_views, task.index, static_cast<std::uint64_t>(slot.frame),
                                      slot.fisheye, ws);
        break;
      case Task::kEncode:
        encode(slot, task.index);
        break;
    }
  }

 private:
  struct Task {
    enum Kind { kEncode, kRgbdBand, kFisheyeBand } kind;
    int slot;
    int index;
  };
  struct Slot {
    int frame = -1;
    bool has_fisheye = false;
    char stamp[32] = {};
    detail::RgbdImages images;
    cv::Mat fisheye;
    std::vector<detail::View> rgb_views;
    std::vector<detail::View> fisheye_views;
    std::array<std::vector<std::uint8_t>, kStreamCount> encoded;
    std::array<std::string, kStreamCount> bases;
    std::array<std::string, kStreamCount> paths;
    std::array<std::string, kStreamCount> errors;
  };

  void prepare(int frame, Slot& slot) {
    slot.frame = frame;
    const std::int64_t stamp_us = frame_stamp_us(frame);
    format_stamp(stamp_us, slot.stamp);
    const double t = static_cast<double>(stamp_us - kStartStamp_us) * 1e-6;
    slot.has_fisheye = scene_.calibration.fisheye.has_value() && frame % kFisheyeDivider == 0;
    for (int k = 0; k < samples_; ++k) {
      const double offset = samples_ > 1 ? (static_cast<double>(k) / (samples_ - 1) - 0.5) * options_.exposure_s : 0.0;
      renderer_.prepare_view(renderer_.rgb_rays(), scene_.T_world_rgb(t + offset), slot.rgb_views[static_cast<std::size_t>(k)]);
      if (slot.has_fisheye) {
        renderer_.prepare_view(*renderer_.fisheye_rays(), scene_.T_world_base(t + offset) * scene_.calibration.fisheye->T_base_cam,
                               slot.fisheye_views[static_cast<std::size_t>(k)]);
      }
    }
  }

  void encode(Slot& slot, int stream) {
    const auto s = static_cast<std::size_t>(stream);
    const cv::Mat& image = stream == kRgb ? slot.images.rgb
                           : stream == kDepth ? slot.images.depth
                           : stream == kIr    ? slot.images.ir
                                              : slot.fisheye;
    std::string& path = slot.paths[s];
    path.assign(slot.bases[s]);
    path += slot.stamp;
    path += ".png";
    try {
      if (!cv::imencode(".png", image, slot.encoded[s], png_params_)) {
        slot.errors[s] = "cannot encode " + path;
        return;
      }
    } catch (const cv::Exception& error) {
      slot.errors[s] = "cannot encode " + path + ": " + error.what();
      return;
    }
    if (auto error = write_bytes(path, slot.encoded[s]); !error.empty()) slot.errors[s] = std::move(error);
  }

  const SceneModel& scene_;
  const SimulationOptions& options_;
  detail::Renderer renderer_;
  WorkerPool pool_;
  int samples_ = 1;
  int rgb_bands_ = 0;
  int fisheye_bands_ = 0;
  std::vector<int> png_params_;
  std::vector<detail::BandWorkspace> workspaces_;
  std::array<Slot, 2> slots_;
  std::vector<Task> tasks_;
};

std::string validate(const SimulationOptions& options) {
  if (scene_description(options.scene).empty()) {
    std::string names;
    for (const auto& name : scene_names()) names += (names.empty() ? "" : ", ") + name;
    return "unknown scene '" + options.scene + "' (scenes: " + names + ")";
  }
  if (options.out_dir.empty()) return "no output folder given";
  if (options.frames < 0 || options.frames > kMaxFrames) {
    return "frames must be 0 (scene default) to " + std::to_string(kMaxFrames) + ", not " + std::to_string(options.frames);
  }
  if (options.first_frame < 0 || options.first_frame > kMaxFrames) {
    return "first_frame must be 0 to " + std::to_string(kMaxFrames) + ", not " + std::to_string(options.first_frame);
  }
  if (options.motion_blur && (options.motion_blur_samples < 3 || options.motion_blur_samples > 15 ||
                              options.motion_blur_samples % 2 == 0)) {
    return "motion_blur_samples must be odd and 3..15, not " + std::to_string(options.motion_blur_samples);
  }
  if (!(options.exposure_s > 0.0) || options.exposure_s > 1.0 / kFrameRate_hz) {
    return "exposure_s must be in (0, 1/30] s, not " + number(options.exposure_s);
  }
  if (!(options.min_depth_m > 0.0) || !(options.max_depth_m > options.min_depth_m) || options.max_depth_m > 13.0) {
    return "depth range must satisfy 0 < min_depth_m < max_depth_m <= 13 m";
  }
  if (options.threads < 0 || options.threads > 256) return "threads must be 0 (all) to 256";
  if (options.png_compression_level < -1 || options.png_compression_level > 9) {
    return "png_compression_level must be -1 (fast) or 0..9";
  }
  return {};
}

std::string prepare_out_dir(const fs::path& out_dir, const SceneModel& scene, bool images) {
  std::error_code ec;
  if (fs::exists(out_dir, ec)) {
    if (!fs::is_directory(out_dir, ec)) return out_dir.string() + " exists and is not a folder";
    if (!fs::is_empty(out_dir, ec)) return out_dir.string() + " is not empty; choose a new or empty folder";
    if (ec) return "cannot read " + out_dir.string() + ": " + ec.message();
  } else if (!fs::create_directories(out_dir, ec) || ec) {
    return "cannot create " + out_dir.string() + ": " + (ec ? ec.message() : std::string("unknown error"));
  }
  if (::access(out_dir.c_str(), W_OK) != 0) return "cannot write into " + out_dir.string() + ": " + std::strerror(errno);
  if (!images) return {};
  std::vector<const char*> folders = {"rgb", "depth"};
  if (scene.has_ir) folders.push_back("ir");
  if (scene.calibration.fisheye) folders.push_back("fisheye");
  for (const char* folder : folders) {
    if (!fs::create_directory(out_dir / folder, ec) || ec) {
      return "cannot create " + (out_dir / folder).string() + ": " + (ec ? ec.message() : std::string("exists"));
    }
  }
  return {};
}

std::string write_text_files(const SceneModel& scene, const SimulationOptions& options, int first, int frames) {
  const fs::path& dir = options.out_dir;
  const int end = first + frames;
  const std::string origin = "# file: 'rankslam simulate " + scene.name + " --seed " + std::to_string(options.seed) +
                             (options.scene_seed != 0 ? " --scene-seed " + std::to_string(options.scene_seed) : std::string()) +
                             " --frames " + std::to_string(frames) +
                             (first > 0 ? " --first-frame " + std::to_string(first) : std::string()) + "'\n";
  auto stamped_list = [&](const char* title, const char* folder, int divider) {
    std::string text = std::string("# ") + title + "\n" + origin + "# timestamp filename\n";
    text.reserve(text.size() + static_cast<std::size_t>(frames) * 48);
    char stamp[32];
    for (int i = first; i < end; ++i) {
      if (i % divider != 0) continue;
      format_stamp(frame_stamp_us(i), stamp);
      text += stamp;
      text += ' ';
      text += folder;
      text += '/';
      text += stamp;
      text += ".png\n";
    }
    return text;
  };
  std::vector<std::pair<std::string, std::string>> files;
  if (options.images) {
    files.emplace_back("rgb.txt", stamped_list("color images", "rgb", 1));
    files.emplace_back("depth.txt", stamped_list("depth maps", "depth", 1));
    if (scene.has_ir) files.emplace_back("ir.txt", stamped_list("infrared images (registered to depth)", "ir", 1));
    if (scene.calibration.fisheye) files.emplace_back("fisheye.txt", stamped_list("fisheye images", "fisheye", kFisheyeDivider));
    std::string associations;
    associations.reserve(static_cast<std::size_t>(frames) * 96);
    char stamp[32];
    for (int i = first; i < end; ++i) {
      format_stamp(frame_stamp_us(i), stamp);
      for (const char* folder : {"rgb", "depth"}) {
        if (folder[0] == 'd') associations += ' ';
        associations += stamp;
        associations += ' ';
        associations += folder;
        associations += '/';
        associations += stamp;
        associations += ".png";
      }
      associations += '\n';
    }
    files.emplace_back("associations.txt", std::move(associations));
  }
  {
    std::string text = "# ground truth trajectory: colour camera optical frame in the world (z up)\n" + origin +
                       "# timestamp tx ty tz qx qy qz qw\n";
    text.reserve(text.size() + static_cast<std::size_t>(frames) * 120);
    char line[256];
    char stamp[32];
    for (int i = first; i < end; ++i) {
      const std::int64_t stamp_us = frame_stamp_us(i);
      format_stamp(stamp_us, stamp);
      const Eigen::Isometry3d T = scene.T_world_rgb(static_cast<double>(stamp_us - kStartStamp_us) * 1e-6);
      const Eigen::Quaterniond q = canonical_quaternion(T.linear());
      const Eigen::Vector3d p = T.translation();
      std::snprintf(line, sizeof line, "%s %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n", stamp, p.x(), p.y(), p.z(), q.x(), q.y(),
                    q.z(), q.w());
      text += line;
    }
    files.emplace_back("groundtruth.txt", std::move(text));
  }
  files.emplace_back("calibration.yaml", calibration_yaml(scene));
  if (const DriveMotion* drive = scene.drive(); drive && scene.calibration.wheels) {
    detail::WheelLogOptions wheel_options;
    wheel_options.seed = options.seed;
    wheel_options.epoch_ns = kStartStamp_us * 1000;
    wheel_options.begin_s = static_cast<double>(frame_stamp_us(first) - kStartStamp_us) * 1e-6;
    wheel_options.end_s = static_cast<double>(frame_stamp_us(end - 1) - kStartStamp_us) * 1e-6;
    wheel_options.tick_noise = options.sensor_noise;
    wheel_options.slip = options.wheel_slip;
    std::string can_log;
    std::vector<detail::SlipSegment> slips;
    detail::build_wheel_log(*drive, *scene.calibration.wheels, wheel_options, can_log, slips);
    files.emplace_back("can.log", std::move(can_log));
    std::string text = "# wheel slip segments: the named wheel's encoder over-counts between the stamps\n" + origin +
                       "# start_stamp end_stamp wheel\n";
    char line[128];
    for (const auto& slip : slips) {
      std::snprintf(line, sizeof line, "%" PRId64 ".%06" PRId64 " %" PRId64 ".%06" PRId64 " %s\n",
                    slip.start_ns / 1'000'000'000, (slip.start_ns % 1'000'000'000) / 1000, slip.end_ns / 1'000'000'000,
                    (slip.end_ns % 1'000'000'000) / 1000, slip.wheel == 0 ? "left" : "right");
      text += line;
    }
    files.emplace_back("slip.txt", std::move(text));
  }
  for (const auto& [name, text] : files) {
    if (auto error = hal::write_file_atomically(dir / name, std::string_view(text)); !error.empty()) return error;
  }
  return {};
}

}  // namespace

std::vector<std::string> scene_names() {
  std::vector<std::string> names;
  for (const auto& scene : kScenes) names.emplace_back(scene.name);
  return names;
}

std::string scene_description(const std::string& scene) {
  for (const auto& info : kScenes) {
    if (scene == info.name) return info.description;
  }
  return {};
}

std::string simulate_recording(const SimulationOptions& options, SimulationSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  if (summary) *summary = SimulationSummary{0, 0.0, 0.0, options.scene};
  if (auto error = validate(options); !error.empty()) return error;
  std::string error;
  std::optional<SceneModel> scene;
  try {
    scene = make_scene(options.scene, options.scene_seed != 0 ? options.scene_seed : options.seed, &error);
  } catch (const std::exception& e) {
    return "cannot build scene '" + options.scene + "': " + e.what();
  }
  if (!scene) return error;
  const int frames = options.frames > 0 ? options.frames : scene->default_frames;
  if (auto dir_error = prepare_out_dir(options.out_dir, *scene, options.images); !dir_error.empty()) return dir_error;
  const int threads = options.threads > 0 ? options.threads
                                          : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  if (options.images) {
    try {
      ImagePipeline pipeline(*scene, options, threads, options.out_dir);
      if (auto run_error = pipeline.run(options.first_frame, frames); !run_error.empty()) return run_error;
    } catch (const std::exception& e) {
      return "simulation of '" + options.scene + "' failed: " + e.what();
    }
  }
  if (auto text_error = write_text_files(*scene, options, options.first_frame, frames); !text_error.empty()) {
    return text_error;
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) {
    summary->frames_written = frames;
    summary->seconds = seconds;
    summary->frames_per_second = seconds > 0.0 ? frames / seconds : 0.0;
  }
  return {};
}

bool is_simulated_recording(const fs::path& dir, const std::string& scene) {
  std::ifstream file(dir / "calibration.yaml");
  std::string first_line;
  return std::getline(file, first_line) && first_line == calibration_header(scene);
}

}  // namespace rankslam::sim
