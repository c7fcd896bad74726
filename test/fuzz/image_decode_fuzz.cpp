// Image files as the replay reader decodes them: the first input byte picks the image the rest
// becomes (colour, depth or IR) in a one-frame 64 x 48 recording whose other images are valid.
// The frame is delivered with images of the calibrated size and type, or skipped and counted
// with a warning; never a crash, a hang or an allocation beyond the limit libFuzzer sets.
#include "fuzz_support.hpp"
#include "rankslam/replay/recording.hpp"
#include "rankslam/replay/replay_camera.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace {

namespace fs = std::filesystem;
using rankslam::fuzz::require;

constexpr int kWidth = 64;
constexpr int kHeight = 48;

std::string png_of(const cv::Mat& image) {
  std::vector<unsigned char> bytes;
  cv::imencode(".png", image, bytes);
  return {bytes.begin(), bytes.end()};
}

// The recording, written once: the fuzzed file is rewritten for every input.
const rankslam::replay::Recording& recording() {
  static const rankslam::replay::Recording opened = [] {
    const fs::path dir = rankslam::fuzz::scratch_dir() / "images";
    fs::create_directories(dir);
    rankslam::fuzz::write_file(dir / "calibration.yaml",
                               "depth_scale: 5000.0\ncameras:\n  rgb:\n    model: pinhole\n    width: 64\n"
                               "    height: 48\n    intrinsics: [50.0, 50.0, 31.5, 23.5]\n");
    rankslam::fuzz::write_file(dir / "associations.txt", "1.0 rgb.png 1.0 depth.png\n");
    rankslam::fuzz::write_file(dir / "ir.txt", "1.0 ir.png\n");
    rankslam::replay::Recording result;
    require(rankslam::replay::open_recording(dir, result).empty(), "the fixture recording opens");
    return result;
  }();
  return opened;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  static const std::string valid_rgb = png_of(cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar(40, 80, 120)));
  static const std::string valid_depth = png_of(cv::Mat(kHeight, kWidth, CV_16UC1, cv::Scalar(5000)));
  static const std::string valid_ir = png_of(cv::Mat(kHeight, kWidth, CV_8UC1, cv::Scalar(60)));
  const auto& rec = recording();
  const std::string_view image(reinterpret_cast<const char*>(data) + 1, size - 1);
  const int target = data[0] % 3;
  rankslam::fuzz::write_file(rec.root / "rgb.png", target == 0 ? image : std::string_view(valid_rgb));
  rankslam::fuzz::write_file(rec.root / "depth.png", target == 1 ? image : std::string_view(valid_depth));
  rankslam::fuzz::write_file(rec.root / "ir.png", target == 2 ? image : std::string_view(valid_ir));

  rankslam::replay::ReplayOptions options;
  options.load_ir = true;
  rankslam::replay::ReplayDepthCamera camera(rec, options);
  require(camera.open().empty(), "the replay camera opens");
  rankslam::hal::RgbdFrame frame;
  const auto status = camera.read(frame, std::chrono::seconds(20));
  require(status != rankslam::hal::ReadStatus::kTimeout, "a frame or the end of the stream within 20 s");
  if (status == rankslam::hal::ReadStatus::kOk) {
    require(frame.rgb.cols == kWidth && frame.rgb.rows == kHeight && frame.rgb.type() == CV_8UC3,
            "a delivered colour image has the calibrated size and type");
    require(frame.depth.cols == kWidth && frame.depth.rows == kHeight && frame.depth.type() == CV_16UC1,
            "a delivered depth image has the calibrated size and type");
    require(frame.ir.empty() || (frame.ir.cols == kWidth && frame.ir.rows == kHeight),
            "a delivered IR image has the calibrated size");
  } else {
    require(camera.counters().corrupt == 1 && !camera.take_warnings().empty(), "a skipped frame is counted and named");
  }
  camera.close();
  return 0;
}
