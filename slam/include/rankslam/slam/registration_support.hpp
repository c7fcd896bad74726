#pragma once

// How much a registration's data fix each direction of the motion: the shape of the matched
// inliers (do they leave a plane?) and the information (inverse covariance) they and a dense
// cloud carry. Used where features are few: to decide whether a feature estimate may hold the
// directions a dense refinement leaves free, and to weight the pose-graph edge it makes.
//
// Information matrices are over ξ = (rotation vector [rad], translation [m]) of a small motion
// applied on the right of T_target_source, i.e. in the source (current) camera frame: the
// convention of the pose graph's edge errors.

#include "rankslam/core/lie.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <span>

namespace rankslam::slam {

using lie::Matrix6d;

/// `point`, seen in image row `row` of an image `height` rows tall whose rows are read out top to
/// bottom over `readout_s`, moved to the frame's mid-exposure camera pose by the camera's
/// `velocity` (angular, then linear; camera frame), to first order.
[[nodiscard]] Eigen::Vector3f rolling_shutter_corrected(const Eigen::Vector3f& point, double row, int height,
                                                        double readout_s, const Eigen::Matrix<double, 6, 1>& velocity);

/// A correspondence source[i] ↔ target[i] with noise sigma_m[i] is an inlier of T_target_source
/// when ‖T·source − target‖ ≤ kInlierSigmas·sigma_m.
inline constexpr double kInlierSigmas = 3.0;

/// The information PlaneIcp's prior takes (on ε = log(T·M⁻¹), in the target frame), for a prior
/// whose strength `step_information` (diagonal: rotation [rad⁻²], translation [m⁻²]) holds the
/// step from its pose M = T_target_prior to the estimate T, ξ = log(M⁻¹·T), as seen from the
/// frame `T_frame_current` maps the current camera into (identity: the camera's own step; the
/// mount T_base_cam: the robot base's). ε = Ad(M)·ξ to first order. (The same diagonal put on ε
/// directly reads a turn about the camera, against a target 20 cm back, as 3.5 mm of translation
/// per degree.)
[[nodiscard]] Matrix6d step_prior_information(const Eigen::Isometry3d& T_target_prior,
                                              const Eigen::Isometry3d& T_frame_current,
                                              const Eigen::Matrix<double, 6, 1>& step_information);

/// Information on ξ (right of M = T_target_prior, the current camera's frame) turned into the
/// information PlaneIcp's prior takes, on ε = log(T·M⁻¹) = Ad(M)·ξ in the target frame.
[[nodiscard]] Matrix6d prior_information_on_target(const Eigen::Isometry3d& T_target_prior,
                                                   const Matrix6d& information_xi);

/// The camera step `step_cam` made by a differential-drive base that can only do what such a base
/// does between two frames: roll forward and turn about its vertical axis. The base motion
/// T_base_cam · step_cam · T_base_cam⁻¹ keeps its forward travel (base x) and its heading change
/// (about base z); its sideways slide, height, roll and pitch are set to zero.
[[nodiscard]] Eigen::Isometry3d drivable_step(const Eigen::Isometry3d& step_cam, const Eigen::Isometry3d& T_base_cam);

/// What a differential-drive base's floor says about the camera motion T_from_to between two
/// key-frames: the base's height, roll and pitch do not change. `T_from_to` is the measurement,
/// the registered motion with those three of the base's set to zero; `information` (over ξ on
/// the right, in the later camera's frame) holds them with `height_sigma_m` and `tilt_sigma_rad`
/// and gives forward travel, sideways motion and heading a floor only (1 rad, 10 m), which keeps
/// it invertible.
struct PlanarConstraint {
  Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Zero();
};
[[nodiscard]] PlanarConstraint planar_constraint(const Eigen::Isometry3d& T_from_to, const Eigen::Isometry3d& T_base_cam,
                                                 double height_sigma_m, double tilt_sigma_rad);

/// A Gaussian belief on a motion: its mean and its information on ξ, a small motion applied on the
/// right of the mean (the current camera's frame).
struct MotionBelief {
  Eigen::Isometry3d mean = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Zero();
};

/// The product of two beliefs on the same motion, to first order about the first one's mean:
/// information I₁ + I₂, mean M₁·exp((I₁ + I₂)⁻¹·I₂·log(M₁⁻¹·M₂)). The first must be positive
/// definite.
[[nodiscard]] MotionBelief combine(const MotionBelief& prior, const MotionBelief& measurement);

/// How the inliers (within 3σ under T_target_source) spread: their count and the √ of the
/// eigenvalues of their source points' covariance, smallest first [m].
struct InlierSpread {
  int inliers = 0;
  Eigen::Vector3d axes_m = Eigen::Vector3d::Zero();
};
[[nodiscard]] InlierSpread inlier_spread(const Eigen::Isometry3d& T_target_source,
                                         std::span<const Eigen::Vector3f> source,
                                         std::span<const Eigen::Vector3f> target, std::span<const double> sigma_m);

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

/// The largest standard deviation of the rotation [rad] that `information` (over ξ) leaves:
/// √ of the largest eigenvalue of the rotation block of its inverse. Infinity where it is
/// singular.
[[nodiscard]] double rotation_sigma_rad(const Matrix6d& information);

/// How well `measured` fixes its least-fixed direction relative to `reference`: the least
/// generalised eigenvalue of (measured, reference). 1: as well as the reference in every
/// direction; 0: some direction is left to the reference alone. 0 when the reference is not
/// positive definite (nothing to compare against).
[[nodiscard]] double least_information_ratio(const Matrix6d& measured, const Matrix6d& reference);

/// Mean of aᵢaᵢᵀ, aᵢ = (pᵢ × nᵢ, nᵢ), over surface points with unit normals: the point-to-plane
/// information per point (of unit noise). A direction the surfaces do not constrain (along a
/// corridor, in the plane of a lone wall) has an eigenvalue near zero.
[[nodiscard]] Matrix6d surface_information(std::span<const Eigen::Vector3f> points,
                                           std::span<const Eigen::Vector3f> normals);

}  // namespace rankslam::slam
