// The index files of a recording as replay opens it: the first input byte picks the file the
// rest becomes (associations.txt, rgb.txt with depth.txt, ir.txt, fisheye.txt or can.log) beside
// a valid calibration.yaml. Refused with a message or accepted, never a
// crash or an escaped exception; what is accepted has finite, ordered frame stamps.
#include "fuzz_support.hpp"
#include "rankslam/replay/recording.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>

namespace {

namespace fs = std::filesystem;
using rankslam::fuzz::require;

constexpr std::string_view kCalibration =
    "depth_scale: 5000.0\n"
    "cameras:\n"
    "  rgb:\n"
    "    model: pinhole\n"
    "    width: 640\n"
    "    height: 480\n"
    "    intrinsics: [517.3, 516.5, 318.6, 255.3]\n";

constexpr std::string_view kAssociations = "1.0 rgb/1.png 1.0 depth/1.png\n2.0 rgb/2.png 2.0 depth/2.png\n";
constexpr std::string_view kDepthList = "1.0 depth/1.png\n2.0 depth/2.png\n";

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const fs::path dir = rankslam::fuzz::scratch_dir() / "recording";
  std::error_code ec;
  fs::remove_all(dir, ec);
  fs::create_directories(dir);
  rankslam::fuzz::write_file(dir / "calibration.yaml", kCalibration);
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  switch (data[0] % 5) {
    case 0: rankslam::fuzz::write_file(dir / "associations.txt", text); break;
    case 1:
      rankslam::fuzz::write_file(dir / "rgb.txt", text);
      rankslam::fuzz::write_file(dir / "depth.txt", kDepthList);
      break;
    case 2:
      rankslam::fuzz::write_file(dir / "associations.txt", kAssociations);
      rankslam::fuzz::write_file(dir / "ir.txt", text);
      break;
    case 3:
      rankslam::fuzz::write_file(dir / "associations.txt", kAssociations);
      rankslam::fuzz::write_file(dir / "fisheye.txt", text);
      break;
    default:
      rankslam::fuzz::write_file(dir / "associations.txt", kAssociations);
      rankslam::fuzz::write_file(dir / "can.log", text);
      break;
  }
  rankslam::replay::Recording recording;
  if (!rankslam::replay::open_recording(dir, recording).empty()) return 0;
  require(!recording.frames.empty(), "an accepted recording has frames");
  for (std::size_t i = 0; i < recording.frames.size(); ++i) {
    require(std::isfinite(recording.frames[i].rgb_stamp_s) && std::isfinite(recording.frames[i].depth_stamp_s),
            "accepted frame stamps are finite");
    if (i > 0) require(recording.frames[i - 1].rgb_stamp_s <= recording.frames[i].rgb_stamp_s, "frames in order");
  }
  for (std::size_t i = 1; i < recording.can_frames.size(); ++i) {
    require(recording.can_frames[i - 1].stamp_ns <= recording.can_frames[i].stamp_ns, "CAN frames in order");
  }
  return 0;
}
