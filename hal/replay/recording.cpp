#include "rankslam/replay/recording.hpp"

#include "rankslam/hal/associate.hpp"
#include "rankslam/hal/candump.hpp"
#include "rankslam/hal/regular_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
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

// A stamp whose nanoseconds fit an int64, as every clock downstream counts them.
bool is_valid_stamp(double stamp_s) { return std::abs(stamp_s) <= kMaxStamp_s; }

// Reads a list file whole (a regular file, size-bounded) and hands each line with its number
// to `parse`, which returns an error message or an empty string; the first error stops.
template <typename Parse>
std::string for_each_line(const fs::path& path, std::size_t max_bytes, Parse&& parse) {
  std::string text;
  if (auto error = hal::read_regular_file(path, max_bytes, text); !error.empty()) return error;
  std::string line;
  int line_number = 0;
  for (std::size_t at = 0; at < text.size();) {
    const auto newline = std::min(text.find('\n', at), text.size());
    line.assign(text, at, newline - at);
    at = newline + 1;
    ++line_number;
    if (auto error = parse(line, line_number); !error.empty()) return error;
  }
  return {};
}

// Reads a "timestamp filename" list (rgb.txt, depth.txt, ir.txt, fisheye.txt).
std::string read_stamped_list(const fs::path& path, std::vector<StampedFile>& entries) {
  return for_each_line(path, hal::kMaxListFileBytes, [&](const std::string& line, int line_number) -> std::string {
    if (is_comment_or_blank(line)) return {};
    std::istringstream fields(line);
    StampedFile entry;
    if (!(fields >> entry.stamp_s >> entry.file) || !is_valid_stamp(entry.stamp_s)) {
      return path.string() + ":" + std::to_string(line_number) + ": expected 'timestamp filename'";
    }
    entries.push_back(std::move(entry));
    return {};
  });
}

std::string read_associations(const fs::path& path, std::vector<FrameEntry>& frames,
                              std::vector<std::string>& warnings) {
  std::vector<int> line_numbers;
  auto error = for_each_line(path, hal::kMaxListFileBytes, [&](const std::string& line, int line_number) -> std::string {
    if (is_comment_or_blank(line)) return {};
    std::istringstream fields(line);
    FrameEntry frame;
    if (!(fields >> frame.rgb_stamp_s >> frame.rgb_file >> frame.depth_stamp_s >> frame.depth_file) ||
        !is_valid_stamp(frame.rgb_stamp_s) || !is_valid_stamp(frame.depth_stamp_s)) {
      return path.string() + ":" + std::to_string(line_number) +
             ": expected 'rgb_stamp rgb_file depth_stamp depth_file'";
    }
    frames.push_back(std::move(frame));
    line_numbers.push_back(line_number);
    return {};
  });
  if (!error.empty() || frames.empty()) return error;
  // One frame per colour stamp, as associate.py keys its lists by stamp: the first line is
  // replayed, each later one with the same stamp (a line pasted twice) dropped with a warning.
  std::vector<std::size_t> order(frames.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return frames[a].rgb_stamp_s < frames[b].rgb_stamp_s; });
  std::vector<bool> duplicate(frames.size(), false);
  std::size_t duplicates = 0;
  for (std::size_t k = 1, first = order[0]; k < order.size(); ++k) {
    const std::size_t i = order[k];
    if (frames[i].rgb_stamp_s != frames[first].rgb_stamp_s) {
      first = i;
      continue;
    }
    duplicate[i] = true;
    if (++duplicates <= 3) {
      warnings.push_back(path.string() + ":" + std::to_string(line_numbers[i]) + ": colour stamp already on line " +
                         std::to_string(line_numbers[first]) + ", line dropped");
    }
  }
  if (duplicates > 3) {
    warnings.push_back(path.string() + ": " + std::to_string(duplicates) + " lines repeating a colour stamp dropped in all");
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (duplicate[i]) continue;
    if (kept != i) frames[kept] = std::move(frames[i]);
    ++kept;
  }
  frames.resize(kept);
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
  std::string header;
  int lines = 0;
  (void)for_each_line(path, hal::kMaxTrajectoryFileBytes, [&](const std::string& line, int) -> std::string {
    if (++lines > 5) return "enough";
    if (!line.empty() && line[0] == '#') header += line + "\n";
    return {};
  });
  return header;
}

// A warning when `stamps_s` (in file order) step backwards: the replay plays them in stamp order,
// which is not the order the file gives when a clock stepped back.
void warn_of_backward_stamps(const std::vector<double>& stamps_s, const fs::path& path, std::vector<std::string>& warnings) {
  std::size_t steps = 0;
  double largest_s = 0.0;
  for (std::size_t i = 1; i < stamps_s.size(); ++i) {
    if (stamps_s[i] >= stamps_s[i - 1]) continue;
    ++steps;
    largest_s = std::max(largest_s, stamps_s[i - 1] - stamps_s[i]);
  }
  if (steps == 0) return;
  char largest[32];
  std::snprintf(largest, sizeof largest, "%.6f", largest_s);
  warnings.push_back(path.string() + ": stamps go backwards " + std::to_string(steps) + " times (by up to " + largest +
                     " s); replayed in stamp order");
}

std::string read_can_log(const fs::path& path, std::vector<hal::CanFrame>& frames,
                         std::vector<std::string>& warnings) {
  int bad_lines = 0;
  auto error = for_each_line(path, hal::kMaxCanLogBytes, [&](const std::string& line, int line_number) -> std::string {
    if (is_comment_or_blank(line)) return {};
    if (auto frame = hal::parse_candump_line(line)) {
      frames.push_back(*frame);
    } else if (++bad_lines <= 3) {
      warnings.push_back(path.string() + ":" + std::to_string(line_number) + ": not a candump -l frame, skipped");
    }
    return {};
  });
  if (!error.empty()) return error;
  if (bad_lines > 3) {
    warnings.push_back(path.string() + ": " + std::to_string(bad_lines) + " malformed lines skipped in all");
  }
  std::vector<double> stamps_s;
  stamps_s.reserve(frames.size());
  for (const hal::CanFrame& frame : frames) stamps_s.push_back(static_cast<double>(frame.stamp_ns) * 1e-9);
  warn_of_backward_stamps(stamps_s, path, warnings);
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

  // Which optional files are there; one that cannot be told (a symbolic-link loop) is an error.
  std::string presence_error;
  const auto present = [&](const char* name) { return hal::path_exists(root / name, presence_error); };
  for (const char* name : {"groundtruth.txt", "calibration.yaml", "associations.txt", "ir.txt", "fisheye.txt", "can.log"}) {
    if (!present(name) && !presence_error.empty()) return presence_error;
  }

  if (present("groundtruth.txt")) {
    if (auto error = hal::check_regular_file(root / "groundtruth.txt", hal::kMaxTrajectoryFileBytes); !error.empty()) {
      return error;
    }
    recording.ground_truth = root / "groundtruth.txt";
  }

  // Calibration: the recording's own file first, then the TUM camera its name or ground truth names.
  if (present("calibration.yaml")) {
    // A calibration is under a kilobyte; the YAML parser would wait on a FIFO or read a device forever.
    if (auto error = hal::check_regular_file(root / "calibration.yaml", std::size_t{1} << 20U); !error.empty()) {
      return error;
    }
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
  if (present("associations.txt")) {
    if (auto error = read_associations(root / "associations.txt", recording.frames, recording.warnings);
        !error.empty()) {
      return error;
    }
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
  if (fs::exists(root / "associations.txt")) {
    std::vector<double> stamps_s;
    stamps_s.reserve(recording.frames.size());
    for (const FrameEntry& frame : recording.frames) stamps_s.push_back(frame.rgb_stamp_s);
    warn_of_backward_stamps(stamps_s, root / "associations.txt", recording.warnings);
  }
  std::stable_sort(recording.frames.begin(), recording.frames.end(),
                   [](const FrameEntry& a, const FrameEntry& b) { return a.rgb_stamp_s < b.rgb_stamp_s; });

  if (present("ir.txt")) {
    std::vector<StampedFile> ir;
    if (auto error = read_stamped_list(root / "ir.txt", ir); !error.empty()) return error;
    std::vector<double> frame_stamps;
    frame_stamps.reserve(recording.frames.size());
    for (const auto& frame : recording.frames) frame_stamps.push_back(frame.depth_stamp_s);
    for (const auto& [i, j] : hal::associate_stamps(frame_stamps, stamps_of(ir), kMaxAssociationGap_s)) {
      recording.frames[i].ir_file = ir[j].file;
    }
  }
  if (present("fisheye.txt")) {
    std::vector<StampedFile> fisheye;
    if (auto error = read_stamped_list(root / "fisheye.txt", fisheye); !error.empty()) return error;
    if (!recording.calibration.fisheye) {
      recording.warnings.push_back((root / "fisheye.txt").string() +
                                   ": no cameras.fisheye in the calibration; fisheye images are ignored");
    } else {
      for (auto& entry : fisheye) recording.fisheye.push_back({entry.stamp_s, std::move(entry.file)});
    }
  }
  if (present("can.log")) {
    if (auto error = read_can_log(root / "can.log", recording.can_frames, recording.warnings); !error.empty()) {
      return error;
    }
  }
  return {};
}

}  // namespace rankslam::replay
