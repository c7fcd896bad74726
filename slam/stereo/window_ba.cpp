#include "rankslam/stereo/window_ba.hpp"

#include <cmath>

#include <ceres/ceres.h>
#include <ceres/rotation.h>

namespace rankslam::stereo {
namespace {

/// Reprojection of a world point into the rectified left camera and, for kStereo, the right one
/// (same row, column shifted by fx·b/Z).
template <bool kStereo>
struct ReprojectionError {
  RectifiedRig rig;
  double u, v, u_right;

  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    T p[3];
    ceres::AngleAxisRotatePoint(pose, point, p);
    p[0] += pose[3];
    p[1] += pose[4];
    p[2] += pose[5];
    // Behind or at the camera: no projection; Ceres rejects the step.
    if (p[2] <= T(1e-3)) return false;
    const T inv_z = T(1.0) / p[2];
    residual[0] = T(rig.fx) * p[0] * inv_z + T(rig.cx) - T(u);
    residual[1] = T(rig.fy) * p[1] * inv_z + T(rig.cy) - T(v);
    if constexpr (kStereo) residual[2] = T(rig.fx) * (p[0] - T(rig.baseline_m)) * inv_z + T(rig.cx) - T(u_right);
    return true;
  }
};

ceres::CostFunction* make_cost(const RectifiedRig& rig, const Observation& o) {
  if (std::isfinite(o.u_right)) {
    return new ceres::AutoDiffCostFunction<ReprojectionError<true>, 3, 6, 3>(
        new ReprojectionError<true>{rig, o.u, o.v, o.u_right});
  }
  return new ceres::AutoDiffCostFunction<ReprojectionError<false>, 2, 6, 3>(
      new ReprojectionError<false>{rig, o.u, o.v, 0.0});
}

using PoseParams = Eigen::Matrix<double, 6, 1>;  // angle-axis, translation of T_cam_world

PoseParams to_params(const Eigen::Isometry3d& T_cam_world) {
  const Eigen::AngleAxisd rotation(T_cam_world.linear());
  PoseParams params;
  params.head<3>() = rotation.angle() * rotation.axis();
  params.tail<3>() = T_cam_world.translation();
  return params;
}

Eigen::Isometry3d from_params(const PoseParams& params) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const double angle = params.head<3>().norm();
  if (angle > 0.0) T.linear() = Eigen::AngleAxisd(angle, params.head<3>() / angle).toRotationMatrix();
  T.translation() = params.tail<3>();
  return T;
}

bool depth_positive(const Eigen::Isometry3d& T_cam_world, const Eigen::Vector3d& p_world) {
  return (T_cam_world * p_world).z() > 1e-3;
}

ceres::Solver::Options solver_options(int max_iterations) {
  ceres::Solver::Options options;
  // Ten poses: the reduced camera system is 60×60, dense beats a sparse factorisation.
  options.linear_solver_type = ceres::DENSE_SCHUR;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  return options;
}

}  // namespace

WindowBaSummary adjust_window(const RectifiedRig& rig, std::span<WindowFrame* const> frames, LandmarkStore& landmarks,
                              const WindowBaConfig& config, std::int64_t stamp) {
  WindowBaSummary summary;
  if (frames.size() < 2) return summary;
  // Count each landmark's observations in the window: one seen once constrains no pose.
  for (const WindowFrame* frame : frames) {
    for (const Observation& o : frame->observations) {
      Landmark* l = landmarks.find(o.landmark);
      if (l == nullptr) continue;
      if (l->stamp != stamp) {
        l->stamp = stamp;
        l->window_observations = 0;
      }
      ++l->window_observations;
    }
  }
  std::vector<PoseParams> poses(frames.size());
  for (std::size_t f = 0; f < frames.size(); ++f) poses[f] = to_params(frames[f]->T_world_cam.inverse());

  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::HuberLoss huber(config.huber_px);
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const Eigen::Isometry3d T_cam_world = frames[f]->T_world_cam.inverse();
    for (const Observation& o : frames[f]->observations) {
      Landmark* l = landmarks.find(o.landmark);
      if (l == nullptr || l->window_observations < 2 || !depth_positive(T_cam_world, l->p_world)) continue;
      problem.AddResidualBlock(make_cost(rig, o), &huber, poses[f].data(), l->p_world.data());
      ++summary.residual_blocks;
    }
  }
  if (summary.residual_blocks == 0) return summary;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    if (problem.HasParameterBlock(poses[f].data())) {
      if (f == 0) problem.SetParameterBlockConstant(poses[f].data());
    }
  }
  if (!problem.HasParameterBlock(poses[0].data())) return summary;  // nothing ties the window to its anchor
  summary.landmarks = problem.NumParameterBlocks() - static_cast<int>(frames.size());
  ceres::Solver::Summary solver_summary;
  ceres::Solve(solver_options(config.max_iterations), &problem, &solver_summary);
  summary.initial_cost = solver_summary.initial_cost;
  summary.final_cost = solver_summary.final_cost;
  summary.solved = solver_summary.IsSolutionUsable();
  if (summary.solved) {
    for (std::size_t f = 1; f < frames.size(); ++f) frames[f]->T_world_cam = from_params(poses[f]).inverse();
  }
  return summary;
}

bool refine_pose(const RectifiedRig& rig, std::span<const Eigen::Vector3d> points_ref,
                 std::span<const Observation> observations, const WindowBaConfig& config, Eigen::Isometry3d& T_cam_ref) {
  if (points_ref.size() != observations.size() || points_ref.size() < 3) return false;
  PoseParams pose = to_params(T_cam_ref);
  // Points are constants: copies the problem can point at.
  std::vector<Eigen::Vector3d> points(points_ref.begin(), points_ref.end());
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  ceres::HuberLoss huber(config.huber_px);
  int blocks = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!depth_positive(T_cam_ref, points[i])) continue;
    problem.AddResidualBlock(make_cost(rig, observations[i]), &huber, pose.data(), points[i].data());
    problem.SetParameterBlockConstant(points[i].data());
    ++blocks;
  }
  if (blocks < 3) return false;
  ceres::Solver::Options options = solver_options(config.max_iterations);
  options.linear_solver_type = ceres::DENSE_QR;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  if (!summary.IsSolutionUsable()) return false;
  T_cam_ref = from_params(pose);
  return true;
}

}  // namespace rankslam::stereo
