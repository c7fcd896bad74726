#include "rankslam/nav/pose_uncertainty.hpp"

#include "rankslam/core/units.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace rankslam::nav {
namespace {

Eigen::Matrix3d hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

}  // namespace

PoseSigmas pose_sigmas(const Eigen::Isometry3d& T_world_cam, const Eigen::Matrix<double, 6, 6>& covariance,
                       const Eigen::Isometry3d& T_base_cam) {
  // T_base_cam·T_world_cam·Exp(ξ)·T_cam_base: the base's position moves by
  // R_ob_c·(v − [t_cb]×·ω) (R_ob_c = R_base_cam·R_world_cam, t_cb the base origin in the camera
  // frame) and its rotation by Exp(R_ob_c·ω) on the left, in the odom frame.
  const Eigen::Matrix3d R = T_base_cam.linear() * T_world_cam.linear();
  const Eigen::Vector3d t_cam_base = T_base_cam.inverse().translation();
  Eigen::Matrix<double, 3, 6> J_position;
  J_position.leftCols<3>() = -R * hat(t_cam_base);
  J_position.rightCols<3>() = R;
  Eigen::Matrix<double, 1, 6> J_yaw = Eigen::Matrix<double, 1, 6>::Zero();
  J_yaw.leftCols<3>() = R.row(2);
  const Eigen::Matrix3d position = J_position * covariance * J_position.transpose();
  const Eigen::Matrix2d horizontal = 0.5 * (position.topLeftCorner<2, 2>() + position.topLeftCorner<2, 2>().transpose());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> solver(horizontal, Eigen::EigenvaluesOnly);
  PoseSigmas sigmas;
  sigmas.position_m = std::sqrt(std::max(0.0, solver.eigenvalues()(1)));
  sigmas.yaw_deg = rad_to_deg(std::sqrt(std::max(0.0, (J_yaw * covariance * J_yaw.transpose())(0, 0))));
  return sigmas;
}

PoseSigmas grown_by_wheels(const PoseSigmas& sigmas, double distance_m, double turned_rad, double wheel_variance_per_m,
                           double track_width_m) {
  if (!(distance_m > 0.0 || turned_rad > 0.0) || !(track_width_m > 0.0)) return sigmas;
  const double rolled_m = std::abs(distance_m) + 0.5 * track_width_m * std::abs(turned_rad);  // per wheel, on average
  PoseSigmas grown;
  grown.position_m = std::sqrt(sigmas.position_m * sigmas.position_m + 0.5 * wheel_variance_per_m * rolled_m);
  const double yaw_variance = 2.0 * wheel_variance_per_m * rolled_m / (track_width_m * track_width_m);
  const double yaw_rad = deg_to_rad(sigmas.yaw_deg);
  grown.yaw_deg = rad_to_deg(std::sqrt(yaw_rad * yaw_rad + yaw_variance));
  return grown;
}

}  // namespace rankslam::nav
