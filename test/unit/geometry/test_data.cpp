#include "test_data.hpp"

#include <fstream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include "rankslam/replay/recording.hpp"
#include "rankslam/sim/simulator.hpp"

namespace rankslam::geometry::testing {

namespace fs = std::filesystem;

namespace {

std::vector<cv::Mat> read_depth_list(const fs::path& root, int count) {
  std::vector<cv::Mat> frames;
  std::ifstream list(root / "depth.txt");
  std::string line;
  while (static_cast<int>(frames.size()) < count && std::getline(list, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    double stamp = 0.0;
    std::string file;
    if (!(fields >> stamp >> file)) continue;
    cv::Mat depth = cv::imread((root / file).string(), cv::IMREAD_ANYDEPTH);
    if (depth.type() == CV_16UC1) frames.push_back(depth);
  }
  return frames;
}

}  // namespace

std::vector<cv::Mat> tum_depth_frames(const std::string& name, int count,
                                      hal::Calibration& calibration) {
#ifdef RANKSLAM_SHARED_DATA
  const fs::path root = fs::path(RANKSLAM_SHARED_DATA) / "tum" / name;
  if (!fs::exists(root / "depth.txt")) return {};
  const auto tum = replay::tum_calibration("freiburg1");
  if (!tum) return {};
  calibration = *tum;
  return read_depth_list(root, count);
#else
  (void)name;
  (void)count;
  (void)calibration;
  return {};
#endif
}

std::vector<cv::Mat> simulated_depth_frames(const std::string& scene, int first, int count,
                                            bool sensor_noise, hal::Calibration& calibration,
                                            std::string& error) {
  sim::SimulationOptions options;
  options.scene = scene;
  options.first_frame = first;
  options.frames = count;
  options.sensor_noise = sensor_noise;
  options.wheel_slip = false;
  options.out_dir = fs::temp_directory_path() /
                    ("rankslam_geometry_test_" + scene + (sensor_noise ? "_noisy_" : "_clean_") +
                     std::to_string(first) + "_" + std::to_string(::getpid()));
  std::error_code ec;
  fs::remove_all(options.out_dir, ec);
  error = sim::simulate_recording(options, nullptr);
  std::vector<cv::Mat> frames;
  if (error.empty()) {
    replay::Recording recording;
    error = replay::open_recording(options.out_dir, recording);
    if (error.empty()) {
      calibration = recording.calibration;
      frames = read_depth_list(options.out_dir, count);
    }
  }
  fs::remove_all(options.out_dir, ec);
  return frames;
}

}  // namespace rankslam::geometry::testing
