#pragma once

// How much a registration's data fix each direction of the motion: the shape of the matched
// inliers (do they leave a plane?) and the information (inverse covariance) they and a dense
// cloud carry. Used where features are few: to decide whether a feature estimate may hold the
// directions a dense refinement leaves free, and to weight the pose-graph edge it makes.
//
// Information matrices are over ξ = (rotation vector [rad], translation [m]) of a small motion
// applied on the right of T_target_source, i.e. in the source (current) camera frame: the
// convention of the pose graph's edge errors.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <span>

namespace rankslam::slam {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// A correspondence source[i] ↔ target[i] with noise sigma_m[i] is an inlier of T_target_source
/// when ‖T·source − target‖ ≤ kInlierSigmas·sigma_m.
inline constexpr double kInlierSigmas = 3.0;

/// √ of the smallest eigenvalue of the covariance of the inliers' source points: how far they
/// leave their best-fitting plane [m]. 0 with fewer than 4 inliers.
[[nodiscard]] double inlier_thickness_m(const Eigen::Isometry3d& T_target_source,
                                        std::span<const Eigen::Vector3f> source,
                                        std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m);

/// Σ over the inliers of BᵢᵀBᵢ / σᵢ², Bᵢ = ∂(T·exp(ξ)·sᵢ)/∂ξ up to the rotation R (which σ-isotropic
/// residuals do not see): the information of the least-squares fit on them.
[[nodiscard]] Matrix6d correspondence_information(const Eigen::Isometry3d& T_target_source,
                                                  std::span<const Eigen::Vector3f> source,
                                                  std::span<const Eigen::Vector3f> target,
                                                  std::span<const double> sigma_m);

/// Mean of aᵢaᵢᵀ, aᵢ = (pᵢ × nᵢ, nᵢ), over surface points with unit normals: the point-to-plane
/// information per point (of unit noise). A direction the surfaces do not constrain (along a
/// corridor, in the plane of a lone wall) has an eigenvalue near zero.
[[nodiscard]] Matrix6d surface_information(std::span<const Eigen::Vector3f> points,
                                           std::span<const Eigen::Vector3f> normals);

}  // namespace rankslam::slam
