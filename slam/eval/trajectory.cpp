#include "rankslam/eval/trajectory.hpp"

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <system_error>

#include "rankslam/hal/atomic_file.hpp"
#include "rankslam/hal/regular_file.hpp"

namespace rankslam::eval {
namespace {

constexpr std::size_t kFieldCount = 8;
constexpr std::array<std::string_view, kFieldCount> kFieldNames = {
    "timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
// Below this length a quaternion has no usable direction; real writers produce length ~1.
constexpr double kMinQuaternionNorm = 1e-6;

bool is_separator(char c) { return c == ' ' || c == '\t' || c == ',' || c == '\r'; }

std::string location(std::string_view source_name, std::size_t line_number) {
  return std::string(source_name) + ":" + std::to_string(line_number) + ": ";
}

/// Shortened, printable copy of a bad token for an error message.
std::string quote_token(std::string_view token) {
  constexpr std::size_t kMaxShown = 32;
  std::string shown;
  for (const char c : token.substr(0, kMaxShown)) {
    shown +=
        (static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7f) ? c : '?';
  }
  if (token.size() > kMaxShown) shown += "...";
  return "'" + shown + "'";
}

/// Parses the whole token as a double (Python float() syntax minus underscores). Returns an
/// empty string or why the token is not a number.
std::string_view parse_double(std::string_view token, double& value) {
  if (!token.empty() && token.front() == '+') token.remove_prefix(1);
  if (token.empty()) return "is not a number";
  const char* const end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  if (ec == std::errc::result_out_of_range) return "is out of range";
  if (ec != std::errc() || ptr != end) return "is not a number";
  return {};
}

}  // namespace

Result<Trajectory> parse_tum_trajectory(std::string_view text, std::string_view source_name) {
  Trajectory trajectory;
  std::size_t line_number = 0;
  while (!text.empty()) {
    ++line_number;
    const std::size_t newline = text.find('\n');
    std::string_view line = text.substr(0, newline);
    text = newline == std::string_view::npos ? std::string_view{} : text.substr(newline + 1);

    std::array<std::string_view, kFieldCount> fields;
    std::size_t field_count = 0;
    std::size_t pos = 0;
    while (pos < line.size()) {
      while (pos < line.size() && is_separator(line[pos])) ++pos;
      if (pos == line.size()) break;
      std::size_t end = pos;
      while (end < line.size() && !is_separator(line[end])) ++end;
      if (field_count == 0 && line[pos] == '#') break;  // comment line
      if (field_count < kFieldCount) fields[field_count] = line.substr(pos, end - pos);
      ++field_count;
      pos = end;
    }
    if (field_count == 0) continue;  // blank or comment
    if (field_count != kFieldCount) {
      return Result<Trajectory>::failure(
          location(source_name, line_number) +
          "expected 8 fields (timestamp tx ty tz qx qy qz qw), found " +
          std::to_string(field_count));
    }

    std::array<double, kFieldCount> values{};
    for (std::size_t i = 0; i < kFieldCount; ++i) {
      std::string_view problem = parse_double(fields[i], values[i]);
      if (problem.empty() && !std::isfinite(values[i])) problem = "is not finite";
      if (!problem.empty()) {
        return Result<Trajectory>::failure(location(source_name, line_number) + "field " +
                                           std::to_string(i + 1) + " (" +
                                           std::string(kFieldNames[i]) + ") " +
                                           quote_token(fields[i]) + " " + std::string(problem));
      }
    }

    // TUM order is qx qy qz qw; Eigen's constructor takes w first.
    Eigen::Quaterniond q(values[7], values[4], values[5], values[6]);
    const double norm = q.norm();
    if (!(norm >= kMinQuaternionNorm) || !std::isfinite(norm)) {
      return Result<Trajectory>::failure(
          location(source_name, line_number) + "quaternion (qx qy qz qw) " +
          quote_token(std::string(fields[4]) + " " + std::string(fields[5]) + " " +
                      std::string(fields[6]) + " " + std::string(fields[7])) +
          " has length " + std::to_string(norm) + " and cannot be normalised");
    }
    q.coeffs() /= norm;

    StampedPose pose;
    pose.stamp_s = values[0];
    pose.T_world_cam.linear() = q.toRotationMatrix();
    pose.T_world_cam.translation() = Eigen::Vector3d(values[1], values[2], values[3]);
    trajectory.push_back(pose);
  }
  return Result<Trajectory>::success(std::move(trajectory));
}

Result<Trajectory> read_tum_trajectory(const std::filesystem::path& path) {
  std::string text;
  if (auto error = hal::read_regular_file(path, hal::kMaxTrajectoryFileBytes, text); !error.empty()) {
    return Result<Trajectory>::failure(error);
  }
  return parse_tum_trajectory(text, path.string());
}

std::string format_tum_trajectory(const Trajectory& trajectory) {
  std::string text = "# timestamp tx ty tz qx qy qz qw\n";
  text.reserve(text.size() + trajectory.size() * 96);
  // Longer than any line of finite values: "%.6f" of -DBL_MAX is 317 characters, "%.9g" at most 16.
  std::array<char, 512> line{};
  for (const StampedPose& pose : trajectory) {
    Eigen::Quaterniond q(pose.T_world_cam.linear());
    q.normalize();
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // one of the two equal quaternions, qw >= 0
    const Eigen::Vector3d t = pose.T_world_cam.translation();
    const int length =
        std::snprintf(line.data(), line.size(), "%.6f %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n",
                      pose.stamp_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
    if (length > 0) {
      text.append(line.data(), std::min(static_cast<std::size_t>(length), line.size() - 1));
    }
  }
  return text;
}

std::string write_tum_trajectory(const std::filesystem::path& path, const Trajectory& trajectory) {
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const StampedPose& pose = trajectory[i];
    if (!std::isfinite(pose.stamp_s) || !pose.T_world_cam.matrix().allFinite()) {
      return "cannot write " + path.string() + ": pose " + std::to_string(i) + " (stamp " +
             std::to_string(pose.stamp_s) + " s) is not finite";
    }
  }
  const std::string text = format_tum_trajectory(trajectory);
  return hal::write_file_atomically(path, std::string_view(text));
}

}  // namespace rankslam::eval
