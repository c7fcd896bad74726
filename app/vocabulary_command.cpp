// `rankslam vocabulary`: SIFT descriptors from recordings' key-frame-like colour frames and
// wide-angle images, clustered into a place-recognition vocabulary (ALGORITHMS.md §6.4).
#include "commands.hpp"
#include "exit_codes.hpp"
#include "robot_config.hpp"

#include "rankslam/camera/depth_camera.hpp"
#include "rankslam/camera/virtual_views.hpp"
#include "rankslam/hal/atomic_file.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"
#include "rankslam/wide/features.hpp"
#include "rankslam/wide/vlad.hpp"

#include <chrono>
#include <iostream>
#include <memory>

namespace rankslam::app {
namespace {

constexpr auto kWait = std::chrono::milliseconds(5000);

/// Appends the descriptors of every `every`-th frame of the recording; an error naming the
/// recording or frame, else empty.
std::string collect(const std::filesystem::path& dir, int every, cv::Mat& descriptors, int& frames, int& images) {
  replay::Recording recording;
  if (auto error = replay::open_recording(dir, recording); !error.empty()) return error;
  for (const auto& warning : recording.warnings) std::cerr << "warning: " << warning << "\n";
  replay::ReplayOptions options;
  options.load_ir = false;
  replay::ReplayDepthCamera camera(recording, options);
  if (auto error = camera.open(); !error.empty()) return error;
  wide::RgbdFeatureExtractor rgbd(camera::DepthCameraModel(recording.calibration));
  wide::RgbdFeatures rgbd_features;
  hal::RgbdFrame frame;
  for (std::uint32_t n = 0;; ++n) {
    const hal::ReadStatus status = camera.read(frame, kWait);
    if (status == hal::ReadStatus::kEndOfStream) break;
    if (status != hal::ReadStatus::kOk) return dir.string() + ": colour frame " + std::to_string(n) + ": " + std::string(to_string(status));
    if (n % static_cast<std::uint32_t>(every) != 0 || !rgbd.extract(frame.rgb, frame.depth, rgbd_features)) continue;
    if (rgbd_features.count > 0) descriptors.push_back(rgbd_features.descriptors.rowRange(0, rgbd_features.count));
    ++frames;
  }
  const std::unique_ptr<replay::ReplayImageCamera> wide_camera = make_replay_wide_camera(recording, options);
  if (!wide_camera) return {};
  if (auto error = wide_camera->open(); !error.empty()) return error;
  const camera::VirtualViews views(*recording.calibration.fisheye, recording.calibration.rgb);
  wide::WideFeatureExtractor extractor(views);
  wide::WideFeatures wide_features;
  hal::ImageFrame image;
  for (std::uint32_t n = 0;; ++n) {
    const hal::ReadStatus status = wide_camera->read(image, kWait);
    if (status == hal::ReadStatus::kEndOfStream) break;
    if (status != hal::ReadStatus::kOk) return dir.string() + ": wide-angle image " + std::to_string(n) + ": " + std::string(to_string(status));
    if (n % static_cast<std::uint32_t>(every) != 0 || !extractor.extract(image.image, wide_features)) continue;
    if (wide_features.count > 0) descriptors.push_back(wide_features.descriptors);
    ++images;
  }
  return {};
}

}  // namespace

int run_vocabulary(const VocabularyArgs& args) {
  cv::Mat descriptors(0, wide::Vocabulary::kDimension, CV_32F);
  for (const auto& dir : args.recordings) {
    int frames = 0;
    int images = 0;
    if (auto error = collect(dir, args.every, descriptors, frames, images); !error.empty()) {
      std::cerr << "error: " << error << "\n";
      return kExitInput;
    }
    std::cout << dir.string() << ": " << frames << " colour frames, " << images << " wide-angle images; "
              << descriptors.rows << " descriptors so far\n";
  }
  if (descriptors.rows < args.words) {
    std::cerr << "error: " << descriptors.rows << " descriptors, fewer than the " << args.words << " words asked for\n";
    return kExitInput;
  }
  // Evenly spaced rows up to the cap: k-means' time grows with them.
  cv::Mat sample = descriptors;
  if (descriptors.rows > args.max_descriptors) {
    sample.create(args.max_descriptors, descriptors.cols, CV_32F);
    for (int i = 0; i < args.max_descriptors; ++i) {
      descriptors.row(static_cast<int>(static_cast<long long>(i) * descriptors.rows / args.max_descriptors)).copyTo(sample.row(i));
    }
  }
  const wide::Vocabulary vocabulary = wide::Vocabulary::train(sample, args.words, args.seed);
  const std::vector<char> bytes = vocabulary.serialise();
  if (auto error = hal::write_file_atomically(args.out, std::span<const char>(bytes)); !error.empty()) {
    std::cerr << "error: " << error << "\n";
    return kExitOutput;
  }
  std::cout << "vocabulary of " << vocabulary.words() << " words from " << sample.rows << " of " << descriptors.rows
            << " descriptors written to " << args.out.string() << "\n";
  return kExitOk;
}

}  // namespace rankslam::app
