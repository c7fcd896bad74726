#pragma once

// Rigid 3D–3D registration: the closed-form solver (Horn 1987 / Umeyama 1991, no scale) and the
// RobustModel for MSSE/RANSAC. Frames: src points are in frame s, dst points in frame t; the
// estimate is T_t_s with dst_i ≈ T_t_s · src_i.

#include <cstdint>
#include <span>
#include <string_view>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "rankslam/robust/status.hpp"

namespace rankslam::robust {

enum class [[nodiscard]] RigidFitStatus : std::uint8_t {
  kOk,
  kTooFewPoints,  ///< Fewer than 3 correspondences (or index list shorter than 3).
  kZeroWeight,    ///< The weights sum to zero.
  kCoincident,    ///< The points (src or dst) are all within min_separation_m of their centroid.
  kCollinear,     ///< The points (src or dst) lie on a line: rotation about it is undetermined.
  kNonFinite,     ///< Non-finite input or output (never returned as a transform).
};

constexpr std::string_view to_string(RigidFitStatus status) {
  switch (status) {
    case RigidFitStatus::kOk: return "ok";
    case RigidFitStatus::kTooFewPoints: return "too-few-points";
    case RigidFitStatus::kZeroWeight: return "zero-weight";
    case RigidFitStatus::kCoincident: return "coincident";
    case RigidFitStatus::kCollinear: return "collinear";
    case RigidFitStatus::kNonFinite: return "non-finite";
  }
  return "unknown";
}

/// Degeneracy limits of the rigid solver.
struct RigidSolverConfig {
  /// Points closer than this [m] count as coincident: in a minimal sample any pair; in a
  /// least-squares fit the weighted RMS distance to the centroid. Range [0, 1].
  double min_separation_m = 1e-3;
  /// Minimal sample: triangle aspect 2·area / (longest side)² below this counts as collinear
  /// (equilateral ≈ 0.87). Rejecting slivers early saves evaluating hopeless hypotheses.
  /// Range [0, 0.8].
  double min_sample_aspect = 1e-2;
  /// Least-squares fit: sqrt(λ_mid / λ_max) of the weighted point covariance (thickness over
  /// length of the set) below this counts as collinear. Range [0, 1).
  double min_thickness_ratio = 1e-3;

  /// Empty when every field is in range, else the name of the first offending field.
  [[nodiscard]] std::string_view validate() const {
    if (!(min_separation_m >= 0.0 && min_separation_m <= 1.0)) return "min_separation_m";
    if (!(min_sample_aspect >= 0.0 && min_sample_aspect <= 0.8)) return "min_sample_aspect";
    if (!(min_thickness_ratio >= 0.0 && min_thickness_ratio < 1.0)) return "min_thickness_ratio";
    return {};
  }
};

/// T_t_s = argmin Σ w_i ‖T·src_i − dst_i‖² over rigid T (weighted Umeyama 1991 without scale:
/// SVD of the weighted cross-covariance, reflection corrected). src and dst are 3×n with
/// n ≥ 3; weights empty (all 1) or n non-negative values. On failure T_t_s is set to identity.
/// Allocates nothing.
RigidFitStatus fit_rigid(const Eigen::Ref<const Eigen::Matrix3Xd>& src,
                         const Eigen::Ref<const Eigen::Matrix3Xd>& dst,
                         std::span<const double> weights, Eigen::Isometry3d& T_t_s,
                         const RigidSolverConfig& config = {});

/// Minimal-sample degeneracy test (3 points each side): any pair closer than min_separation_m,
/// or a triangle aspect below min_sample_aspect.
RigidFitStatus check_minimal_sample(const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, const RigidSolverConfig& config);

/// Kinect-style depth noise (Khoshelham & Elberink 2012): σ_z = a·z² along the ray plus a
/// lateral term, used to give each correspondence its own noise scale.
struct DepthNoiseModel {
  /// a in σ_z = a·z² [1/m]; 1.425e-3 for the Kinect v1 (Khoshelham & Elberink 2012).
  double axial_coefficient_per_m = 1.425e-3;
  /// Lateral noise per axis [m].
  double lateral_sigma_m = 1e-3;
};

/// σ_i of the residual ‖T·src_i − dst_i‖ from the noise of both measured points:
/// σ_i² = (a·z_s²)² + (a·z_t²)² + 4·σ_lat² (two lateral axes per point; rotation keeps norms).
/// src and dst must be in their own camera frames (z = depth > 0). Writes n values to out.
/// kInvalidInput on size mismatch or non-finite/non-positive depth.
RobustStatus correspondence_sigmas_m(const Eigen::Ref<const Eigen::Matrix3Xd>& src,
                                     const Eigen::Ref<const Eigen::Matrix3Xd>& dst,
                                     const DepthNoiseModel& noise, std::span<double> out);

/// Rigid 3D–3D registration for estimate_msse / estimate_ransac: p = 6, sample size 3,
/// residual r_i = ‖T·src_i − dst_i‖ in metres. Holds structure-of-arrays copies of the
/// correspondences so that a hypothesis' residuals are evaluated as vectorised array
/// expressions: in double for segmentation and refits, and in float (twice the SIMD width) for
/// ranking the H hypotheses, where float's ~1 µm error at 4 m is far below any residual that
/// decides a ranking.
class RigidModel {
 public:
  using Params = Eigen::Isometry3d;  ///< T_t_s
  static constexpr int kSampleSize = 3;
  static constexpr int kParameterCount = 6;
  static constexpr bool kScoresAreSquaredResiduals = true;

  /// Set-up (allocates): room for up to max_points correspondences.
  explicit RigidModel(int max_points, const RigidSolverConfig& config = {});

  /// Per call, no allocation: copies the correspondences (column i of src matches column i of
  /// dst) and the optional non-negative per-correspondence weights, which weight the refit only
  /// (e.g. W_P / W_G of the fused registration, docs/methods.md §6). On error the model is empty.
  RobustStatus set_correspondences(const Eigen::Ref<const Eigen::Matrix3Xd>& src,
                                   const Eigen::Ref<const Eigen::Matrix3Xd>& dst,
                                   std::span<const double> weights = {});

  [[nodiscard]] int size() const { return size_; }
  [[nodiscard]] int capacity() const { return static_cast<int>(src_.rows()); }
  [[nodiscard]] const RigidSolverConfig& config() const { return config_; }

  static Params default_params() { return Params::Identity(); }
  [[nodiscard]] bool sample_degenerate(std::span<const int> sample) const;
  [[nodiscard]] bool fit_sample(std::span<const int> sample, Params& T_t_s) const;
  [[nodiscard]] bool fit_inliers(std::span<const int> inliers, const double* point_weights,
                                 Params& T_t_s) const;
  void squared_residuals(const Params& T_t_s, int begin, int count, double* out) const;
  /// r_i² evaluated in float: the ranking score used to select hypotheses.
  void selection_scores(const Params& T_t_s, int begin, int count, double* out) const;
  /// selection_scores, each multiplied by inverse_variances[i − begin] when that is not null
  /// (the per-point 1/σ² normalisation), into out; returns how many are below `bound`. The same
  /// values as selection_scores followed by the scaling, in one pass over the points (a vector at
  /// a time where the CPU has a vector target): ranking the hypotheses is most of an MSSE.
  int scaled_selection_scores(const Params& T_t_s, int begin, int count,
                              const double* inverse_variances, double bound, double* out) const;

  /// Point i of src (frame s) / dst (frame t).
  [[nodiscard]] Eigen::Vector3d src(int i) const { return src_.row(i).transpose(); }
  [[nodiscard]] Eigen::Vector3d dst(int i) const { return dst_.row(i).transpose(); }

 private:
  using PointRows = Eigen::Matrix<double, Eigen::Dynamic, 3>;  // column-major: x, y, z columns
  using PointRowsF = Eigen::Matrix<float, Eigen::Dynamic, 3>;
  RigidSolverConfig config_;
  PointRows src_;
  PointRows dst_;
  PointRowsF src_f_;
  PointRowsF dst_f_;
  Eigen::VectorXd weights_;
  bool has_weights_ = false;
  int size_ = 0;
};

/// Hypothesis gate around a predicted motion (e.g. from wheel odometry): accepts T_t_s only when
/// it is within max_translation_m and max_rotation_rad of the prediction.
struct RigidMotionGate {
  Eigen::Isometry3d T_t_s_predicted = Eigen::Isometry3d::Identity();
  double max_translation_m = 0.1;
  double max_rotation_rad = 0.2;

  [[nodiscard]] bool operator()(const Eigen::Isometry3d& T_t_s) const;
};

/// Rotation angle of R_a⁻¹·R_b in radians, and the translation difference norm in metres.
[[nodiscard]] double rotation_difference_rad(const Eigen::Isometry3d& a,
                                             const Eigen::Isometry3d& b);
[[nodiscard]] double translation_difference_m(const Eigen::Isometry3d& a,
                                              const Eigen::Isometry3d& b);

}  // namespace rankslam::robust
