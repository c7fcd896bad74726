#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "rankslam/eval/result.hpp"

namespace rankslam::eval {

/// One pose of a trajectory: the camera (or body) frame in the trajectory's world frame.
struct StampedPose {
  double stamp_s = 0.0;  ///< seconds, same clock as the other trajectory it is compared with
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();
};

/// Poses in file order; the metrics sort by stamp themselves and accept any order.
using Trajectory = std::vector<StampedPose>;

/// Parses TUM trajectory text: one pose per line, "timestamp tx ty tz qx qy qz qw", fields
/// separated by spaces, tabs or commas (as the benchmark's scripts accept). Lines whose first
/// non-blank character is '#' and blank lines are skipped. Every other line must have exactly
/// eight finite numbers and a quaternion of non-zero length, which is normalised.
/// `source_name` names the text in errors, which read "<source_name>:<line>: <what is wrong>".
[[nodiscard]] Result<Trajectory> parse_tum_trajectory(std::string_view text,
                                                      std::string_view source_name);

/// Reads a TUM trajectory file; errors name the file and, for content errors, the line.
[[nodiscard]] Result<Trajectory> read_tum_trajectory(const std::filesystem::path& path);

/// TUM text with a "# timestamp tx ty tz qx qy qz qw" header: stamps with 6 decimals
/// (microseconds), positions and quaternions with 9 significant digits, quaternion with qw >= 0.
[[nodiscard]] std::string format_tum_trajectory(const Trajectory& trajectory);

/// Writes format_tum_trajectory() atomically (temporary file, fsync, rename). Returns an empty
/// string on success, otherwise a message naming the file, or the pose that is not finite.
[[nodiscard]] std::string write_tum_trajectory(const std::filesystem::path& path,
                                               const Trajectory& trajectory);

}  // namespace rankslam::eval
