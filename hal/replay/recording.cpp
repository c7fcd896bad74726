#include "rankslam/replay/recording.hpp"

#include "rankslam/hal/associate.hpp"
#include "rankslam/hal/candump.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <sstream>

namespace rankslam::replay {
namespace {

namespace fs = std::filesystem;

struct StampedFile {
  double stamp_s = 0.0;
  std::string file;
};

bool is_comment_or_blank(const std::string& line) {
  const auto first = line.find_first_not_of(" \t\r");
  return first == std::string::npos || line[first] == '#';
}

// Reads a "timestamp filename" list (rgb.txt, depth.txt, ir.txt, fisheye.txt).
std::string read_stamped_list(const fs::path& path, std::vector<StampedFile>& entries) {
  std::ifstream in(path);
  if (!in) return "cannot open " + path.string();
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (is_comment_or_blank(line)) continue;
    std::istringstream fields(line);
    StampedFile entry;
    if (!(fields >> entry.stamp_s >> entry.file) || !std::isfinite(entry.stamp_s)) {
      return path.string() + ":" + std::to_string(line_number) + ": expected 'timestamp filename'";
    }
    entries.push_back(std::move(entry));
  }
  return {};
}

std::string read_associations(const fs::path& path, std::vector<FrameEntry>& frames) {
  std::ifstream in(path);
  if (!in) return "cannot open " + path.string();
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (is_comment_or_blank(line)) continue;
    std::istringstream fields(line);
    FrameEntry frame;
    if (!(fields >> frame.rgb_stamp_s >> frame.rgb_file >> frame.depth_stamp_s >> frame.depth_file)) {
      return path.string() + ":" + std::to_string(line_number) +
             ": expected 'rgb_stamp rgb_file depth_stamp depth_file'";
    }
    frames.push_back(std::move(frame));
  }
  return {};
}

std::vector<double> stamps_of(const std::vector<StampedFile>& entries) {
  std::vector<double> stamps;
  stamps.reserve(entries.size());
  for (const auto& entry : entries) stamps.push_back(entry.stamp_s);
  return stamps;
}

std::string lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

// The TUM camera named by a folder name ("fr1_rpy_head", "rgbd_dataset_freiburg2_desk") or by
// the ground-truth header ("# file: 'rgbd_dataset_freiburg1_rpy.bag'").
std::optional<std::string> tum_camera_named_in(const std::string& text) {
  const std::string name = lower(text);
  for (const char digit : {'1', '2', '3'}) {
    const std::string long_name = std::string("freiburg") + digit;
    const std::string short_name = std::string("fr") + digit;
    if (name.find(long_name) != std::string::npos) return long_name;
    const auto at = name.find(short_name);
    // "fr1" must stand alone or be followed by a separator, not be part of a longer word.
    if (at != std::string::npos && (at == 0 || !std::isalpha(static_cast<unsigned char>(name[at - 1]))) &&
        (at + 3 == name.size() || !std::isdigit(static_cast<unsigned char>(name[at + 3])))) {
      return long_name;
    }
  }
  return std::nullopt;
}

std::string ground_truth_header(const fs::path& path) {
  std::ifstream in(path);
  std::string header;
  std::string line;
  for (int i = 0; i < 5 && std::getline(in, line); ++i) {
    if (!line.empty() && line[0] == '#') header += line + "\n";
  }
  return header;
}

std::string read_can_log(const fs::path& path, std::vector<hal::CanFrame>& frames,
                         std::vector<std::string>& warnings) {
  std::ifstream in(path);
  if (!in) return "cannot open " + path.string();
  std::string line;
  int line_number = 0;
  int bad_lines = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (is_comment_or_blank(line)) continue;
    if (auto frame = hal::parse_candump_line(line)) {
      frames.push_back(*frame);
    } else if (++bad_lines <= 3) {
      warnings.push_back(path.string() + ":" + std::to_string(line_number) + ": not a candump -l frame, skipped");
    }
  }
  if (bad_lines > 3) {
    warnings.push_back(path.string() + ": " + std::to_string(bad_lines) + " malformed lines skipped in all");
  }
  std::stable_sort(frames.begin(), frames.end(),
                   [](const hal::CanFrame& a, const hal::CanFrame& b) { return a.stamp_ns < b.stamp_ns; });
  return {};
}

}  // namespace

std::optional<hal::Calibration> tum_calibration(const std::string& camera_name) {
  hal::Calibration calibration;
  calibration.depth_scale = 5000.0;
  auto& rgb = calibration.rgb;
  rgb.model = hal::CameraModel::kPinhole;
  rgb.width = 640;
  rgb.height = 480;
  // Published colour intrinsics of the TUM RGB-D benchmark cameras.
  if (camera_name == "freiburg1") {
    rgb.fx = 517.3; rgb.fy = 516.5; rgb.cx = 318.6; rgb.cy = 255.3;
    rgb.distortion = {0.2624, -0.9531, -0.0054, 0.0026, 1.1633};
  } else if (camera_name == "freiburg2") {
    rgb.fx = 520.9; rgb.fy = 521.0; rgb.cx = 325.1; rgb.cy = 249.7;
    rgb.distortion = {0.2312, -0.7849, -0.0033, -0.0001, 0.9172};
  } else if (camera_name == "freiburg3") {
    rgb.fx = 535.4; rgb.fy = 539.2; rgb.cx = 320.1; rgb.cy = 247.6;
    rgb.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  } else {
    return std::nullopt;
  }
  calibration.source = "TUM " + camera_name + " published calibration";
  return calibration;
}

std::string open_recording(const fs::path& root, Recording& recording) {
  recording = Recording{};
  recording.root = root;
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return root.string() + ": not a directory";

  if (fs::exists(root / "groundtruth.txt")) recording.ground_truth = root / "groundtruth.txt";

  // Calibration: the recording's own file first, then the TUM camera its name or ground truth names.
  if (fs::exists(root / "calibration.yaml")) {
    if (auto error = load_calibration_yaml(root / "calibration.yaml", recording.calibration); !error.empty()) {
      return error;
    }
  } else {
    auto camera = tum_camera_named_in(fs::weakly_canonical(root, ec).filename().string());
    if (!camera && recording.ground_truth) camera = tum_camera_named_in(ground_truth_header(*recording.ground_truth));
    if (!camera) {
      return root.string() +
             ": no calibration.yaml, and neither the folder name nor groundtruth.txt names a TUM camera "
             "(freiburg1/2/3); add a calibration.yaml (see README, 'Recording format')";
    }
    recording.calibration = *tum_calibration(*camera);
  }

  // Colour-depth pairs: associations.txt when present, otherwise nearest stamps within 0.02 s.
  if (fs::exists(root / "associations.txt")) {
    if (auto error = read_associations(root / "associations.txt", recording.frames); !error.empty()) return error;
  } else {
    std::vector<StampedFile> rgb;
    std::vector<StampedFile> depth;
    if (auto error = read_stamped_list(root / "rgb.txt", rgb); !error.empty()) return error;
    if (auto error = read_stamped_list(root / "depth.txt", depth); !error.empty()) return error;
    for (const auto& [i, j] : hal::associate_stamps(stamps_of(rgb), stamps_of(depth), kMaxAssociationGap_s)) {
      recording.frames.push_back({rgb[i].stamp_s, rgb[i].file, depth[j].stamp_s, depth[j].file, {}});
    }
    const std::size_t unmatched = rgb.size() - recording.frames.size();
    if (unmatched > 0) {
      recording.warnings.push_back((root / "rgb.txt").string() + ": " + std::to_string(unmatched) +
                                   " colour images have no depth image within 0.02 s and are not replayed");
    }
  }
  if (recording.frames.empty()) return root.string() + ": no associated colour and depth images";
  std::stable_sort(recording.frames.begin(), recording.frames.end(),
                   [](const FrameEntry& a, const FrameEntry& b) { return a.rgb_stamp_s < b.rgb_stamp_s; });

  if (fs::exists(root / "ir.txt")) {
    std::vector<StampedFile> ir;
    if (auto error = read_stamped_list(root / "ir.txt", ir); !error.empty()) return error;
    std::vector<double> frame_stamps;
    frame_stamps.reserve(recording.frames.size());
    for (const auto& frame : recording.frames) frame_stamps.push_back(frame.depth_stamp_s);
    for (const auto& [i, j] : hal::associate_stamps(frame_stamps, stamps_of(ir), kMaxAssociationGap_s)) {
      recording.frames[i].ir_file = ir[j].file;
    }
  }
  if (fs::exists(root / "fisheye.txt")) {
    std::vector<StampedFile> fisheye;
    if (auto error = read_stamped_list(root / "fisheye.txt", fisheye); !error.empty()) return error;
    if (!recording.calibration.fisheye) {
      recording.warnings.push_back((root / "fisheye.txt").string() +
                                   ": no cameras.fisheye in the calibration; fisheye images are ignored");
    } else {
      for (auto& entry : fisheye) recording.fisheye.push_back({entry.stamp_s, std::move(entry.file)});
    }
  }
  if (fs::exists(root / "can.log")) {
    if (auto error = read_can_log(root / "can.log", recording.can_frames, recording.warnings); !error.empty()) {
      return error;
    }
  }
  return {};
}

}  // namespace rankslam::replay
