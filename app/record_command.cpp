// `rankslam record`: live drivers → recording format. Builds the camera (and CAN bus) the robot
// configuration names and hands every frame to the recording writer; no encoding here.
#include "commands.hpp"
#include "exit_codes.hpp"
#include "robot_config.hpp"

#include "rankslam/openni2/openni2_camera.hpp"
#include "rankslam/record/recording_writer.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/socketcan/socketcan_bus.hpp"

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <memory>
#include <thread>

namespace rankslam::app {
namespace {

std::atomic<bool> g_stop_record{false};

extern "C" void request_record_stop(int /*signal*/) { g_stop_record.store(true); }

/// Installs SIGINT/SIGTERM handlers for its lifetime.
class RecordStopSignals {
 public:
  RecordStopSignals() {
    g_stop_record = false;
    struct sigaction action {};
    action.sa_handler = request_record_stop;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, &old_int_);
    sigaction(SIGTERM, &action, &old_term_);
  }
  ~RecordStopSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  RecordStopSignals(const RecordStopSignals&) = delete;
  RecordStopSignals& operator=(const RecordStopSignals&) = delete;

 private:
  struct sigaction old_int_ {};
  struct sigaction old_term_ {};
};

}  // namespace

int run_record(const RecordArgs& args) {
  RobotConfig robot;
  robot.camera_source = CameraSource::kOpenNI2;  // no configuration: the first OpenNI2 device
  if (!args.config.empty()) {
    if (auto error = load_robot_config(args.config, robot); !error.empty()) {
      std::cerr << "error: " << error << "\n";
      return kExitInput;
    }
  }
  if (!(args.seconds >= 0.0)) {
    std::cerr << "error: --seconds must not be negative\n";
    return kExitUsage;
  }

  // Set-up: camera, bus and writer; everything that may fail happens before the first frame.
  // Before the camera: a replay camera's reader thread reads the recording until the camera goes.
  replay::Recording source_recording;
  std::unique_ptr<hal::DepthCamera> camera;
  openni2::OpenNI2Camera* openni2_camera = nullptr;
  replay::ReplayDepthCamera* replay_camera = nullptr;
  std::string camera_name;
  if (robot.camera_source == CameraSource::kOpenNI2) {
    openni2::OpenNI2Options options;
    if (auto error = openni2_options_from(robot, options); !error.empty()) {
      std::cerr << "error: " << args.config.string() << ": camera.calibration: " << error << "\n";
      return kExitInput;
    }
    auto driver = std::make_unique<openni2::OpenNI2Camera>(options);
    openni2_camera = driver.get();
    camera = std::move(driver);
    camera_name = "openni2:" + robot.camera_location;
  } else {
    if (auto error = replay::open_recording(robot.camera_location, source_recording); !error.empty()) {
      std::cerr << "error: " << args.config.string() << ": camera.source: " << error << "\n";
      return kExitInput;
    }
    replay::ReplayOptions options;
    options.rate = robot.replay_rate;
    options.max_frames = robot.max_frames;
    auto driver = std::make_unique<replay::ReplayDepthCamera>(source_recording, options);
    replay_camera = driver.get();
    camera = std::move(driver);
    camera_name = "replay:" + robot.camera_location;
  }
  if (auto error = camera->open(); !error.empty()) {
    std::cerr << "error: camera " << camera_name << ": " << error << "\n";
    return kExitInput;
  }
  if (openni2_camera != nullptr) std::cout << openni2_camera->describe() << "\n";

  std::unique_ptr<socketcan::SocketCanBus> bus;
  if (robot.can_interface_given) {
    socketcan::SocketCanOptions options;
    options.interface_name = robot.can_interface;
    options.error_frames = false;
    bus = std::make_unique<socketcan::SocketCanBus>(options);
    if (auto error = bus->open(); !error.empty()) {
      std::cerr << "error: CAN interface " << robot.can_interface << ": " << error << "\n";
      return kExitInput;
    }
  }

  record::RecordingWriterOptions writer_options;
  writer_options.write_can = bus != nullptr;
  writer_options.can_interface = robot.can_interface;
  record::RecordingWriter writer(args.out, writer_options);
  // The configured mounting goes into the recording, so its replay knows the base frame.
  hal::Calibration calibration = camera->calibration();
  if (robot.camera_mounting && !calibration.rgb.T_base_cam_given) {
    calibration.rgb.T_base_cam = *robot.camera_mounting;
    calibration.rgb.T_base_cam_given = true;
  }
  // The wide-angle camera: wide_camera.device, or a replayed recording's wide-angle images.
  std::unique_ptr<hal::Camera> wide_camera;
  std::string wide_name;
  {
    replay::ReplayOptions wide_options;
    wide_options.rate = robot.replay_rate;
    if (auto error = make_wide_camera(robot, calibration, replay_camera != nullptr ? &source_recording : nullptr,
                                      wide_options, wide_camera, wide_name);
        !error.empty()) {
      std::cerr << "error: " << args.config.string() << ": " << error << "\n";
      return kExitInput;
    }
  }
  if (wide_camera) {
    if (auto error = wide_camera->open(); !error.empty()) {
      std::cerr << "error: wide-angle camera " << wide_name << ": " << error << "\n";
      return kExitInput;
    }
  }
  if (auto error = writer.open(calibration); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitOutput;
  }
  std::cout << "recording " << camera_name << (wide_camera ? ", wide-angle " + wide_name : std::string())
            << (bus ? " and CAN " + robot.can_interface : std::string()) << " into " << args.out.string() << std::endl;

  const RecordStopSignals signals;
  std::atomic<bool> stop_can{false};
  std::thread can_reader;
  if (bus) {
    can_reader = std::thread([&] {
      hal::CanFrame can_frame;
      while (!stop_can.load()) {
        const hal::ReadStatus status = bus->receive(can_frame, std::chrono::milliseconds(50));
        if (status == hal::ReadStatus::kOk) {
          (void)writer.push_can(can_frame);
        } else if (status == hal::ReadStatus::kFault) {
          std::this_thread::sleep_for(std::chrono::milliseconds(50));  // the bus reopens on its own
        }
      }
    });
  }

  // The wide-angle camera is read on its own thread: its rate and faults never hold up the RGB-D frames.
  std::atomic<bool> stop_wide{false};
  std::atomic<std::uint64_t> wide_images{0};
  std::atomic<std::uint64_t> wide_faults{0};
  std::thread wide_reader;
  if (wide_camera) {
    wide_reader = std::thread([&] {
      hal::ImageFrame image;
      while (!stop_wide.load()) {
        const hal::ReadStatus status = wide_camera->read(image, std::chrono::milliseconds(100));
        if (status == hal::ReadStatus::kOk) {
          ++wide_images;
          (void)writer.push_wide(image);  // a full queue drops the image; counted by the writer
        } else if (status == hal::ReadStatus::kEndOfStream) {
          break;
        } else if (status == hal::ReadStatus::kFault) {
          ++wide_faults;
        }
      }
    });
  }

  const auto start = std::chrono::steady_clock::now();
  hal::RgbdFrame frame;
  std::uint64_t frames = 0;
  std::uint64_t camera_faults = 0;
  bool interrupted = false;
  bool end_of_stream = false;
  for (;;) {
    if (g_stop_record.load()) {
      interrupted = true;
      break;
    }
    if (args.frames > 0 && frames >= args.frames) break;
    if (args.seconds > 0.0 && std::chrono::steady_clock::now() - start >= std::chrono::duration<double>(args.seconds)) break;
    const hal::ReadStatus status = camera->read(frame, std::chrono::milliseconds(100));
    if (status == hal::ReadStatus::kEndOfStream) {
      end_of_stream = true;
      break;
    }
    if (status == hal::ReadStatus::kFault) {
      if (camera_faults++ == 0) std::cerr << "warning: camera fault; retrying\n";
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      continue;
    }
    if (status != hal::ReadStatus::kOk) continue;
    ++frames;
    (void)writer.push(frame);  // a full queue drops the frame; counted by the writer
  }

  stop_can = true;
  if (can_reader.joinable()) can_reader.join();
  // A played recording's wide-angle images are recorded to their end too.
  if (!end_of_stream || dynamic_cast<replay::ReplayStream*>(wide_camera.get()) == nullptr) stop_wide = true;
  if (wide_reader.joinable()) wide_reader.join();
  if (wide_camera) wide_camera->close();
  if (bus) bus->close();
  camera->close();
  const std::string write_error = writer.close();
  const record::RecordingCounters counters = writer.counters();
  std::printf("frames captured %llu  written %llu  dropped (writer queue full) %llu  failed %llu  IR %llu  CAN %llu "
              "(dropped %llu)%s%s\n",
              static_cast<unsigned long long>(frames), static_cast<unsigned long long>(counters.frames_written),
              static_cast<unsigned long long>(counters.frames_dropped),
              static_cast<unsigned long long>(counters.frames_failed), static_cast<unsigned long long>(counters.ir_written),
              static_cast<unsigned long long>(counters.can_written), static_cast<unsigned long long>(counters.can_dropped),
              end_of_stream ? "  (end of source)" : "", interrupted ? "  (interrupted)" : "");
  if (openni2_camera != nullptr) {
    const auto& c = openni2_camera->counters();
    std::printf("camera: device dropped %llu, unpaired %llu, faults %llu, reopens %llu\n",
                static_cast<unsigned long long>(c.dropped), static_cast<unsigned long long>(c.unpaired),
                static_cast<unsigned long long>(c.faults), static_cast<unsigned long long>(c.reopens));
  }
  if (wide_camera) {
    std::printf("wide-angle images captured %llu  written %llu  dropped %llu  failed %llu  camera faults %llu\n",
                static_cast<unsigned long long>(wide_images.load()), static_cast<unsigned long long>(counters.wide_written),
                static_cast<unsigned long long>(counters.wide_dropped), static_cast<unsigned long long>(counters.wide_failed),
                static_cast<unsigned long long>(wide_faults.load()));
  }
  if (replay_camera != nullptr) {
    for (const auto& warning : replay_camera->take_warnings()) std::cerr << "warning: " << warning << "\n";
  }
  if (auto* stream = dynamic_cast<replay::ReplayStream*>(wide_camera.get()); stream != nullptr) {
    for (const auto& warning : stream->take_warnings()) std::cerr << "warning: " << warning << "\n";
  }
  if (!write_error.empty()) {
    std::cerr << "error: " << write_error << "\n";
    return kExitOutput;
  }
  if (counters.frames_written == 0) {
    std::cerr << "error: no frame was recorded from " << camera_name << "\n";
    return kExitInput;
  }
  return interrupted ? kExitInterrupted : kExitOk;
}

}  // namespace rankslam::app
