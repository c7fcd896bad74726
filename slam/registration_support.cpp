#include "rankslam/slam/registration_support.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace rankslam::slam {
namespace {

template <class Visit>
void for_each_inlier(const Eigen::Isometry3d& T_target_source, std::span<const Eigen::Vector3f> source,
                     std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m, Visit&& visit) {
  const Eigen::Isometry3f T = T_target_source.cast<float>();
  const std::size_t n = std::min({source.size(), target.size(), sigma_m.size()});
  for (std::size_t i = 0; i < n; ++i) {
    const double residual_m = static_cast<double>((T * source[i] - target[i]).norm());
    if (residual_m <= kInlierSigmas * sigma_m[i]) visit(source[i].cast<double>(), sigma_m[i]);
  }
}

}  // namespace

Matrix6d adjoint(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.rotation();
  const Eigen::Vector3d t = T.translation();
  Eigen::Matrix3d t_cross;
  t_cross << 0.0, -t.z(), t.y(), t.z(), 0.0, -t.x(), -t.y(), t.x(), 0.0;
  Matrix6d result = Matrix6d::Zero();
  result.topLeftCorner<3, 3>() = R;
  result.bottomLeftCorner<3, 3>() = t_cross * R;
  result.bottomRightCorner<3, 3>() = R;
  return result;
}

Matrix6d step_prior_information(const Eigen::Isometry3d& T_target_prior, const Eigen::Isometry3d& T_frame_current,
                                const Eigen::Matrix<double, 6, 1>& step_information) {
  // ξ_frame = Ad(T_frame_current)·ξ and ξ = Ad(M⁻¹)·ε.
  const Matrix6d to_step = adjoint(T_frame_current) * adjoint(T_target_prior.inverse());
  return to_step.transpose() * step_information.asDiagonal() * to_step;
}

double inlier_thickness_m(const Eigen::Isometry3d& T_target_source, std::span<const Eigen::Vector3f> source,
                          std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_sq = Eigen::Matrix3d::Zero();
  int count = 0;
  for_each_inlier(T_target_source, source, target, sigma_m, [&](const Eigen::Vector3d& p, double /*sigma*/) {
    sum += p;
    sum_sq += p * p.transpose();
    ++count;
  });
  if (count < 4) return 0.0;
  const Eigen::Vector3d mean = sum / count;
  const Eigen::Matrix3d covariance = sum_sq / count - mean * mean.transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> spread(covariance, Eigen::EigenvaluesOnly);
  return std::sqrt(std::max(0.0, spread.eigenvalues()(0)));
}

Matrix6d correspondence_information(const Eigen::Isometry3d& T_target_source, std::span<const Eigen::Vector3f> source,
                                    std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m) {
  Matrix6d information = Matrix6d::Zero();
  for_each_inlier(T_target_source, source, target, sigma_m, [&](const Eigen::Vector3d& s, double sigma) {
    // T·exp(ξ)·s ≈ T·s + R·(ω × s + τ): B = [−[s]×  I].
    Eigen::Matrix<double, 3, 6> B;
    B << 0.0, s.z(), -s.y(), 1.0, 0.0, 0.0,  //
        -s.z(), 0.0, s.x(), 0.0, 1.0, 0.0,   //
        s.y(), -s.x(), 0.0, 0.0, 0.0, 1.0;
    information += B.transpose() * B / (sigma * sigma);
  });
  return information;
}

Matrix6d surface_information(std::span<const Eigen::Vector3f> points, std::span<const Eigen::Vector3f> normals) {
  Matrix6d information = Matrix6d::Zero();
  const std::size_t n = std::min(points.size(), normals.size());
  if (n == 0) return information;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = points[i].cast<double>();
    const Eigen::Vector3d normal = normals[i].cast<double>();
    Eigen::Matrix<double, 6, 1> a;
    a << p.cross(normal), normal;
    information.selfadjointView<Eigen::Lower>().rankUpdate(a);
  }
  information = information.selfadjointView<Eigen::Lower>();
  return information / static_cast<double>(n);
}

}  // namespace rankslam::slam
