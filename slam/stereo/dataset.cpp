#include "rankslam/stereo/dataset.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
#include <string_view>

#include <yaml-cpp/yaml.h>

namespace rankslam::stereo {
namespace fs = std::filesystem;
using eval::Result;

namespace {

bool read_text(const fs::path& path, std::string& text) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::ostringstream buffer;
  buffer << in.rdbuf();
  text = buffer.str();
  return !in.bad();
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

/// Splits on any of `separators`, dropping empty fields.
std::vector<std::string_view> split(std::string_view line, std::string_view separators) {
  std::vector<std::string_view> fields;
  std::size_t start = 0;
  while (start <= line.size()) {
    const std::size_t end = line.find_first_of(separators, start);
    const std::string_view field = trim(line.substr(start, end == std::string_view::npos ? std::string_view::npos : end - start));
    if (!field.empty()) fields.push_back(field);
    if (end == std::string_view::npos) break;
    start = end + 1;
  }
  return fields;
}

bool parse_double(std::string_view text, double& value) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return error == std::errc{} && end == text.data() + text.size() && std::isfinite(value);
}

bool parse_int64(std::string_view text, std::int64_t& value) {
  // EuRoC's ground truth writes integer nanoseconds with a ".0000000000" tail.
  if (const auto dot = text.find('.'); dot != std::string_view::npos) {
    if (text.find_first_not_of('0', dot + 1) != std::string_view::npos) return false;
    text = text.substr(0, dot);
  }
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  return error == std::errc{} && end == text.data() + text.size();
}

/// Lines of `text` with their 1-based numbers; blank lines and '#' comments skipped.
template <class Visit>
std::string for_each_line(const std::string& text, Visit&& visit) {
  std::size_t start = 0;
  int number = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    ++number;
    const std::string_view line = trim(std::string_view(text).substr(start, end - start));
    start = end + 1;
    if (line.empty() || line.front() == '#') continue;
    if (std::string error = visit(line, number); !error.empty()) return error;
  }
  return {};
}

std::string at_line(const fs::path& file, int line, std::string_view what) {
  return file.string() + ":" + std::to_string(line) + ": " + std::string(what);
}

Result<std::vector<double>> yaml_numbers(const YAML::Node& node, const fs::path& file, const char* field,
                                         std::size_t count) {
  const std::string prefix = file.string() + ": field '" + field + "': ";
  if (!node) return Result<std::vector<double>>::failure(prefix + "missing");
  if (!node.IsSequence() || node.size() != count) {
    return Result<std::vector<double>>::failure(prefix + "expected a list of " + std::to_string(count) + " numbers");
  }
  std::vector<double> values;
  for (const auto& item : node) {
    double value = 0.0;
    if (!item.IsScalar() || !parse_double(item.Scalar(), value)) {
      return Result<std::vector<double>>::failure(prefix + "not a finite number: " + (item.IsScalar() ? item.Scalar() : "?"));
    }
    values.push_back(value);
  }
  return Result<std::vector<double>>::success(std::move(values));
}

/// One EuRoC cam*/sensor.yaml: intrinsics, radtan distortion, resolution, T_BS (camera in body).
Result<std::pair<CameraIntrinsics, Eigen::Isometry3d>> read_sensor_yaml(const fs::path& file) {
  using R = Result<std::pair<CameraIntrinsics, Eigen::Isometry3d>>;
  std::string text;
  if (!read_text(file, text)) return R::failure(file.string() + ": cannot be read");
  // OpenCV's "%YAML:1.0" directive is not YAML 1.2; yaml-cpp rejects it.
  if (text.rfind("%YAML", 0) == 0) text = "#" + text;
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& error) {
    return R::failure(file.string() + ":" + std::to_string(error.mark.line + 1) + ": " + error.msg);
  }
  if (!root.IsMap()) return R::failure(file.string() + ": not a YAML map");
  if (root["camera_model"] && root["camera_model"].as<std::string>("") != "pinhole") {
    return R::failure(file.string() + ": field 'camera_model': only pinhole is supported, not " +
                      root["camera_model"].as<std::string>(""));
  }
  if (root["distortion_model"] && root["distortion_model"].as<std::string>("") != "radial-tangential") {
    return R::failure(file.string() + ": field 'distortion_model': only radial-tangential is supported, not " +
                      root["distortion_model"].as<std::string>(""));
  }
  auto intrinsics = yaml_numbers(root["intrinsics"], file, "intrinsics", 4);
  if (!intrinsics) return R::failure(intrinsics.error());
  auto distortion = yaml_numbers(root["distortion_coefficients"], file, "distortion_coefficients", 4);
  if (!distortion) return R::failure(distortion.error());
  auto resolution = yaml_numbers(root["resolution"], file, "resolution", 2);
  if (!resolution) return R::failure(resolution.error());
  if (!root["T_BS"] || !root["T_BS"].IsMap()) return R::failure(file.string() + ": field 'T_BS': missing");
  auto t_bs = yaml_numbers(root["T_BS"]["data"], file, "T_BS.data", 16);
  if (!t_bs) return R::failure(t_bs.error());

  CameraIntrinsics camera;
  const auto& k = intrinsics.value();
  camera.fu = k[0];
  camera.fv = k[1];
  camera.cu = k[2];
  camera.cv = k[3];
  std::copy(distortion.value().begin(), distortion.value().end(), camera.radtan.begin());
  const auto& size = resolution.value();
  if (!(size[0] >= 1 && size[1] >= 1 && size[0] <= 65536 && size[1] <= 65536)) {
    return R::failure(file.string() + ": field 'resolution': not a positive image size");
  }
  camera.size = cv::Size(static_cast<int>(size[0]), static_cast<int>(size[1]));
  if (!(camera.fu > 0.0 && camera.fv > 0.0)) return R::failure(file.string() + ": field 'intrinsics': focal lengths must be positive");
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) m(i / 4, i % 4) = t_bs.value()[static_cast<std::size_t>(i)];
  const Eigen::Matrix3d r = m.topLeftCorner<3, 3>();
  if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-3 || r.determinant() < 0.0) {
    return R::failure(file.string() + ": field 'T_BS': the rotation is not orthonormal");
  }
  Eigen::Isometry3d T_body_cam = Eigen::Isometry3d::Identity();
  // Re-orthonormalise: the published matrices are printed to 12 digits.
  T_body_cam.linear() = Eigen::Quaterniond(r).normalized().toRotationMatrix();
  T_body_cam.translation() = m.topRightCorner<3, 1>();
  return R::success({camera, T_body_cam});
}

/// A cam*/data.csv: "stamp_ns,filename" lines.
Result<std::vector<std::pair<std::int64_t, std::string>>> read_euroc_index(const fs::path& file) {
  using R = Result<std::vector<std::pair<std::int64_t, std::string>>>;
  std::string text;
  if (!read_text(file, text)) return R::failure(file.string() + ": cannot be read");
  std::vector<std::pair<std::int64_t, std::string>> rows;
  const std::string error = for_each_line(text, [&](std::string_view line, int number) -> std::string {
    const auto fields = split(line, ",");
    if (fields.size() != 2) return at_line(file, number, "expected 'timestamp [ns],filename'");
    std::int64_t stamp = 0;
    if (!parse_int64(fields[0], stamp) || stamp < 0) return at_line(file, number, "timestamp is not a non-negative integer");
    if (!rows.empty() && stamp <= rows.back().first) return at_line(file, number, "timestamps must increase");
    rows.emplace_back(stamp, std::string(fields[1]));
    return {};
  });
  if (!error.empty()) return R::failure(error);
  if (rows.empty()) return R::failure(file.string() + ": no images listed");
  return R::success(std::move(rows));
}

/// EuRoC's own ground-truth CSV: ns, p x y z, q w x y z (the left camera in groundtruth_cam0_euroc.txt).
Result<eval::Trajectory> read_euroc_ground_truth(const fs::path& file) {
  std::string text;
  if (!read_text(file, text)) return Result<eval::Trajectory>::failure(file.string() + ": cannot be read");
  eval::Trajectory trajectory;
  const std::string error = for_each_line(text, [&](std::string_view line, int number) -> std::string {
    const auto fields = split(line, ", \t");
    if (fields.size() < 8) return at_line(file, number, "expected 'ns, x, y, z, qw, qx, qy, qz'");
    std::int64_t stamp = 0;
    if (!parse_int64(fields[0], stamp)) return at_line(file, number, "timestamp is not an integer number of ns");
    double v[7];
    for (int i = 0; i < 7; ++i) {
      if (!parse_double(fields[static_cast<std::size_t>(i) + 1], v[i])) return at_line(file, number, "not a finite number");
    }
    Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
    if (q.norm() < 1e-9) return at_line(file, number, "zero quaternion");
    eval::StampedPose pose;
    pose.stamp_s = static_cast<double>(stamp) * 1e-9;
    pose.T_world_cam.linear() = q.normalized().toRotationMatrix();
    pose.T_world_cam.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    trajectory.push_back(pose);
    return {};
  });
  if (!error.empty()) return Result<eval::Trajectory>::failure(error);
  if (trajectory.empty()) return Result<eval::Trajectory>::failure(file.string() + ": no poses");
  return Result<eval::Trajectory>::success(std::move(trajectory));
}

}  // namespace

Result<eval::Trajectory> parse_kitti_poses(const std::string& text, const std::vector<double>& stamps_s,
                                           const std::string& source_name) {
  eval::Trajectory trajectory;
  const fs::path file(source_name);
  std::string error = for_each_line(text, [&](std::string_view line, int number) -> std::string {
    const auto fields = split(line, " \t");
    if (fields.size() != 12) return at_line(file, number, "expected 12 numbers (a 3x4 pose, row-major)");
    Eigen::Matrix<double, 3, 4> m;
    for (int i = 0; i < 12; ++i) {
      if (!parse_double(fields[static_cast<std::size_t>(i)], m(i / 4, i % 4))) return at_line(file, number, "not a finite number");
    }
    const Eigen::Matrix3d r = m.leftCols<3>();
    if ((r.transpose() * r - Eigen::Matrix3d::Identity()).norm() > 1e-2 || r.determinant() < 0.0) {
      return at_line(file, number, "the rotation is not orthonormal");
    }
    if (trajectory.size() >= stamps_s.size()) return at_line(file, number, "more poses than frames in times.txt");
    eval::StampedPose pose;
    pose.stamp_s = stamps_s[trajectory.size()];
    pose.T_world_cam.linear() = Eigen::Quaterniond(r).normalized().toRotationMatrix();
    pose.T_world_cam.translation() = m.col(3);
    trajectory.push_back(pose);
    return {};
  });
  if (error.empty() && trajectory.size() != stamps_s.size()) {
    error = source_name + ": " + std::to_string(trajectory.size()) + " poses for " + std::to_string(stamps_s.size()) + " frames";
  }
  if (!error.empty()) return Result<eval::Trajectory>::failure(error);
  return Result<eval::Trajectory>::success(std::move(trajectory));
}

Result<StereoDataset> read_euroc(const fs::path& dir, const fs::path& ground_truth) {
  using R = Result<StereoDataset>;
  const fs::path mav = dir / "mav0";
  if (!fs::is_directory(mav)) return R::failure(mav.string() + ": not a directory (EuRoC ASL layout expected)");
  StereoDataset dataset;
  dataset.layout = DatasetLayout::euroc;
  auto left = read_sensor_yaml(mav / "cam0" / "sensor.yaml");
  if (!left) return R::failure(left.error());
  auto right = read_sensor_yaml(mav / "cam1" / "sensor.yaml");
  if (!right) return R::failure(right.error());
  dataset.calibration.left = left.value().first;
  dataset.calibration.right = right.value().first;
  dataset.calibration.T_right_left = right.value().second.inverse() * left.value().second;
  dataset.calibration.rectified = false;
  if (dataset.calibration.T_right_left.translation().norm() < 1e-6) {
    return R::failure((mav / "cam1" / "sensor.yaml").string() + ": field 'T_BS': the two cameras coincide (no baseline)");
  }

  auto left_index = read_euroc_index(mav / "cam0" / "data.csv");
  if (!left_index) return R::failure(left_index.error());
  auto right_index = read_euroc_index(mav / "cam1" / "data.csv");
  if (!right_index) return R::failure(right_index.error());
  std::map<std::int64_t, std::string> right_by_stamp(right_index.value().begin(), right_index.value().end());
  for (const auto& [stamp, name] : left_index.value()) {
    const auto match = right_by_stamp.find(stamp);
    if (match == right_by_stamp.end()) {
      ++dataset.unpaired_frames;
      continue;
    }
    StereoFrameFiles frame;
    frame.stamp_ns = stamp;
    frame.stamp_s = static_cast<double>(stamp) * 1e-9;
    frame.left = mav / "cam0" / "data" / name;
    frame.right = mav / "cam1" / "data" / match->second;
    dataset.frames.push_back(std::move(frame));
  }
  if (dataset.frames.empty()) {
    return R::failure((mav / "cam1" / "data.csv").string() + ": no image shares a timestamp with cam0/data.csv");
  }

  fs::path gt_file = ground_truth;
  if (gt_file.empty()) {
    if (fs::exists(dir / "groundtruth.txt")) {
      gt_file = dir / "groundtruth.txt";
    } else if (fs::exists(dir / "groundtruth_cam0_euroc.txt")) {
      gt_file = dir / "groundtruth_cam0_euroc.txt";
    }
  }
  if (!gt_file.empty()) {
    auto trajectory = gt_file.filename() == "groundtruth_cam0_euroc.txt" ? read_euroc_ground_truth(gt_file)
                                                                          : eval::read_tum_trajectory(gt_file);
    if (!trajectory) return R::failure(trajectory.error());
    dataset.ground_truth = std::move(trajectory).value();
    dataset.ground_truth_file = gt_file;
  }
  return R::success(std::move(dataset));
}

Result<StereoDataset> read_kitti(const fs::path& dir, const fs::path& ground_truth) {
  using R = Result<StereoDataset>;
  StereoDataset dataset;
  dataset.layout = DatasetLayout::kitti;
  const fs::path calib = dir / "calib.txt";
  std::string text;
  if (!read_text(calib, text)) return R::failure(calib.string() + ": cannot be read");
  std::optional<Eigen::Matrix<double, 3, 4>> projections[2];
  std::string error = for_each_line(text, [&](std::string_view line, int number) -> std::string {
    const auto colon = line.find(':');
    if (colon == std::string_view::npos) return at_line(calib, number, "expected 'NAME: 12 numbers'");
    const std::string_view name = trim(line.substr(0, colon));
    if (name != "P0" && name != "P1") return {};
    const auto fields = split(line.substr(colon + 1), " \t");
    if (fields.size() != 12) return at_line(calib, number, std::string(name) + ": expected 12 numbers (3x4, row-major)");
    Eigen::Matrix<double, 3, 4> p;
    for (int i = 0; i < 12; ++i) {
      if (!parse_double(fields[static_cast<std::size_t>(i)], p(i / 4, i % 4))) {
        return at_line(calib, number, std::string(name) + ": not a finite number");
      }
    }
    projections[name == "P0" ? 0 : 1] = p;
    return {};
  });
  if (!error.empty()) return R::failure(error);
  for (int i = 0; i < 2; ++i) {
    if (!projections[i]) return R::failure(calib.string() + ": field 'P" + std::to_string(i) + "': missing");
  }
  const Eigen::Matrix<double, 3, 4>& p0 = *projections[0];
  const Eigen::Matrix<double, 3, 4>& p1 = *projections[1];
  if (!(p0(0, 0) > 0.0 && p0(1, 1) > 0.0) || (p0.leftCols<3>() - p1.leftCols<3>()).norm() > 1e-6 * p0(0, 0)) {
    return R::failure(calib.string() + ": field 'P1': P0 and P1 must share one rectified camera matrix with positive focal lengths");
  }
  const Eigen::Matrix3d k = p0.leftCols<3>();
  // P_i = K·[I | t_i]: t_i = K⁻¹·P_i's last column is camera i's offset from the rectified reference.
  const Eigen::Vector3d t0 = k.inverse() * p0.col(3);
  const Eigen::Vector3d t1 = k.inverse() * p1.col(3);
  dataset.calibration.T_right_left = Eigen::Isometry3d::Identity();
  dataset.calibration.T_right_left.translation() = t1 - t0;
  if (!(dataset.calibration.T_right_left.translation().x() < 0.0)) {
    return R::failure(calib.string() + ": field 'P1': camera 1 must lie right of camera 0 (P1[0][3] < P0[0][3])");
  }
  dataset.calibration.rectified = true;

  const fs::path times = dir / "times.txt";
  if (!read_text(times, text)) return R::failure(times.string() + ": cannot be read");
  std::vector<double> stamps;
  error = for_each_line(text, [&](std::string_view line, int number) -> std::string {
    double stamp = 0.0;
    if (!parse_double(line, stamp) || stamp < 0.0) return at_line(times, number, "expected one non-negative time in seconds");
    if (!stamps.empty() && stamp <= stamps.back()) return at_line(times, number, "times must increase");
    stamps.push_back(stamp);
    return {};
  });
  if (!error.empty()) return R::failure(error);
  if (stamps.empty()) return R::failure(times.string() + ": no frames");
  for (std::size_t i = 0; i < stamps.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.png", i);
    StereoFrameFiles frame;
    frame.stamp_s = stamps[i];
    frame.stamp_ns = static_cast<std::int64_t>(std::llround(stamps[i] * 1e9));
    frame.left = dir / "image_0" / name;
    frame.right = dir / "image_1" / name;
    if (!fs::exists(frame.left)) return R::failure(frame.left.string() + ": missing (times.txt line " + std::to_string(i + 1) + ")");
    if (!fs::exists(frame.right)) return R::failure(frame.right.string() + ": missing (times.txt line " + std::to_string(i + 1) + ")");
    dataset.frames.push_back(std::move(frame));
  }
  // Image size from the first left image's PNG header: set-up must not decode the sequence.
  {
    std::ifstream png(dataset.frames.front().left, std::ios::binary);
    unsigned char header[24] = {};
    png.read(reinterpret_cast<char*>(header), sizeof header);
    if (!png || header[1] != 'P' || header[2] != 'N' || header[3] != 'G') {
      return R::failure(dataset.frames.front().left.string() + ": not a PNG image");
    }
    const auto be32 = [&](int at) {
      return (static_cast<int>(header[at]) << 24) | (header[at + 1] << 16) | (header[at + 2] << 8) | header[at + 3];
    };
    dataset.calibration.left.size = cv::Size(be32(16), be32(20));
  }
  CameraIntrinsics camera;
  camera.size = dataset.calibration.left.size;
  camera.fu = k(0, 0);
  camera.fv = k(1, 1);
  camera.cu = k(0, 2);
  camera.cv = k(1, 2);
  dataset.calibration.left = camera;
  dataset.calibration.right = camera;

  fs::path gt_file = ground_truth;
  if (gt_file.empty() && fs::exists(dir / "poses.txt")) gt_file = dir / "poses.txt";
  if (!gt_file.empty()) {
    std::string gt_text;
    if (!read_text(gt_file, gt_text)) return R::failure(gt_file.string() + ": cannot be read");
    // A TUM file (8 fields) is also accepted for --ground-truth; KITTI's own has 12.
    std::size_t first = gt_text.find_first_not_of(" \t\r\n");
    while (first != std::string::npos && gt_text[first] == '#') {
      first = gt_text.find('\n', first);
      if (first != std::string::npos) first = gt_text.find_first_not_of(" \t\r\n", first);
    }
    const std::string first_line = first == std::string::npos ? std::string() : gt_text.substr(first, gt_text.find('\n', first) - first);
    auto trajectory = split(first_line, " \t,").size() == 8 ? eval::parse_tum_trajectory(gt_text, gt_file.string())
                                                          : parse_kitti_poses(gt_text, stamps, gt_file.string());
    if (!trajectory) return R::failure(trajectory.error());
    dataset.ground_truth = std::move(trajectory).value();
    dataset.ground_truth_file = gt_file;
  }
  return R::success(std::move(dataset));
}

Result<StereoDataset> read_stereo_dataset(const fs::path& dir, const fs::path& ground_truth) {
  if (fs::is_directory(dir / "mav0")) return read_euroc(dir, ground_truth);
  if (fs::exists(dir / "calib.txt")) return read_kitti(dir, ground_truth);
  if (!fs::is_directory(dir)) return Result<StereoDataset>::failure(dir.string() + ": not a directory");
  return Result<StereoDataset>::failure(dir.string() + ": neither a EuRoC (mav0/) nor a KITTI (calib.txt) stereo sequence");
}

}  // namespace rankslam::stereo
