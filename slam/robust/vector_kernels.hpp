#pragma once

// The robust models' SIMD kernels, written once with Highway for every vector unit and
// dispatched at run time to the best one this CPU has (callers use them where
// parallel::vector_kernels_enabled()). Without fused multiply-adds (the project builds with
// -ffp-contract=off), each gives its model's portable expression's values bit for bit.

#include <Eigen/Core>

namespace rankslam::robust::vector {

/// RigidModel::scaled_selection_scores over whole vectors of points from 0 on: the float
/// expression ((r0·x + r1·y) + r2·z + t − d)² summed over the rows as Eigen evaluates it, widened
/// to double and multiplied by inverse_variances[i] (when not null), into out. Returns the count
/// below `bound`; `done` is how many points it covered.
int rigid_scores(const float* sx, const float* sy, const float* sz, const float* dx, const float* dy,
                 const float* dz, const Eigen::Matrix3f& r, const Eigen::Vector3f& t, int count,
                 const double* inverse_variances, double bound, double* out, int& done);

/// OrientationModel::scaled_selection_scores over whole vectors of normals from 0 on:
/// 1 − ((d_x·n_x + d_y·n_y) + d_z·n_z), times inverse_variances[i] (when not null), into out.
/// Returns the count below `bound`; `done` is how many normals it covered.
int orientation_scores(const double* nx, const double* ny, const double* nz, const Eigen::Vector3d& direction,
                       int count, const double* inverse_variances, double bound, double* out, int& done);

}  // namespace rankslam::robust::vector
