#pragma once

// The pose graph's edge residual, shared by the graph's solve and the local bundle adjustment's
// edge priors (Ceres autodiff functor; graph-internal).

#include <Eigen/Geometry>
#include <ceres/rotation.h>

namespace rankslam::graph {

// r = √Ω · ξ(T_from_to⁻¹ · T_w_from⁻¹ · T_w_to), ξ = (rotation vector, translation): the SO(3)×R³
// log described in pose_graph.hpp. Autodiff: the exact rotation log (QuaternionToAngleAxis has
// a small-angle branch with correct derivatives) is cheap enough at 14 parameters.
class EdgeResidual {
 public:
  EdgeResidual(const Eigen::Isometry3d& T_from_to, const Eigen::Matrix<double, 6, 6>& sqrt_information)
      : q_to_from_(Eigen::Quaterniond(T_from_to.linear()).normalized().conjugate()),
        t_from_to_(T_from_to.translation()),
        sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* q_w_a_data, const T* t_w_a_data, const T* q_w_b_data,
                  const T* t_w_b_data, T* residual_data) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q_w_a(q_w_a_data);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_w_a(t_w_a_data);
    const Eigen::Map<const Eigen::Quaternion<T>> q_w_b(q_w_b_data);
    const Eigen::Map<const Eigen::Matrix<T, 3, 1>> t_w_b(t_w_b_data);

    // Estimated T_a_b = T_w_a⁻¹ · T_w_b, then E = Z⁻¹ · T_a_b.
    const Eigen::Quaternion<T> q_a_w = q_w_a.conjugate();
    const Eigen::Quaternion<T> q_a_b = q_a_w * q_w_b;
    const Eigen::Matrix<T, 3, 1> t_a_b = q_a_w * (t_w_b - t_w_a);
    const Eigen::Quaternion<T> q_z_inv = q_to_from_.template cast<T>();
    const Eigen::Quaternion<T> q_error = q_z_inv * q_a_b;
    const Eigen::Matrix<T, 3, 1> t_error = q_z_inv * (t_a_b - t_from_to_.template cast<T>());

    Eigen::Matrix<T, 6, 1> xi;
    const T q_error_wxyz[4] = {q_error.w(), q_error.x(), q_error.y(), q_error.z()};
    ceres::QuaternionToAngleAxis(q_error_wxyz, xi.data());
    xi.template tail<3>() = t_error;

    Eigen::Map<Eigen::Matrix<T, 6, 1>> residual(residual_data);
    residual = sqrt_information_.template cast<T>() * xi;
    return true;
  }

 private:
  Eigen::Quaterniond q_to_from_;  // Z⁻¹'s rotation
  Eigen::Vector3d t_from_to_;
  Eigen::Matrix<double, 6, 6> sqrt_information_;
};

}  // namespace rankslam::graph
