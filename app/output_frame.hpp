#pragma once

#include "rankslam/eval/trajectory.hpp"

#include <Eigen/Geometry>

#include <string>
#include <string_view>

namespace rankslam::app {

/// The frame trajectory.txt and map.ply are written in (README "Frames").
enum class OutputFrame {
  kCamera,  ///< The first frame's camera optical frame (x right, y down, z forward); poses of the camera.
  kBase,    ///< The map frame: the base at the first frame (x forward, y left, z up); poses of the base.
};

[[nodiscard]] const char* to_string(OutputFrame frame);

/// The frame `--frame` names ("camera", "base"; empty: base when the camera mounting is known,
/// camera otherwise). Error when the name is neither, or base is asked for without a mounting.
[[nodiscard]] std::string choose_output_frame(std::string_view requested, bool mounting_known, OutputFrame& frame);

/// Camera poses in the first camera's frame re-expressed in `frame`: T_base_cam · T · T_base_cam⁻¹
/// for the base.
[[nodiscard]] eval::Trajectory in_output_frame(const eval::Trajectory& camera_poses, OutputFrame frame,
                                               const Eigen::Isometry3d& T_base_cam);

/// The transform taking map points (first camera frame) into `frame`.
[[nodiscard]] Eigen::Isometry3d output_from_world(OutputFrame frame, const Eigen::Isometry3d& T_base_cam);

/// "translation [x, y, z] m, roll pitch yaw [r, p, y] deg" of a camera mounting.
[[nodiscard]] std::string describe_mounting(const Eigen::Isometry3d& T_base_cam);

}  // namespace rankslam::app
