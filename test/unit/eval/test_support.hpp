#pragma once

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rankslam/eval/trajectory.hpp"

namespace rankslam::eval::test {

inline Eigen::Isometry3d make_pose(const Eigen::Vector3d& position_m,
                                   const Eigen::Quaterniond& orientation) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = orientation.normalized().toRotationMatrix();
  pose.translation() = position_m;
  return pose;
}

/// A smooth 3D path with turning orientation (a helix with a wobble), sampled at rate_hz.
inline Trajectory helix(double start_s, double duration_s, double rate_hz) {
  Trajectory trajectory;
  const auto count = static_cast<int>(std::floor(duration_s * rate_hz)) + 1;
  for (int k = 0; k < count; ++k) {
    const double t = start_s + k / rate_hz;
    const double s = t - start_s;
    const Eigen::Vector3d p(1.5 * std::cos(0.4 * s), 0.8 * std::sin(0.4 * s),
                            0.3 * s + 0.1 * std::sin(2.0 * s));
    const Eigen::Quaterniond q(Eigen::AngleAxisd(0.4 * s, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.2 * std::sin(s), Eigen::Vector3d::UnitX()));
    trajectory.push_back({t, make_pose(p, q)});
  }
  return trajectory;
}

/// A file in the temporary directory that is removed with the object.
class TempFile {
 public:
  explicit TempFile(const std::string& name)
      : path_(std::filesystem::temp_directory_path() /
              ("rankslam_eval_" + std::to_string(::getpid()) + "_" + name)) {}
  ~TempFile() {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline std::filesystem::path shared_trajectories_dir() {
  return std::filesystem::path(RANKSLAM_SHARED_DATA) / "trajectories";
}

}  // namespace rankslam::eval::test
