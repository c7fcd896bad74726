// The robust models' Highway kernels (vector_kernels.hpp). foreach_target.h compiles this file
// once per vector target; the HWY_ONCE part at the end dispatches to the CPU's best one.
#include "vector_kernels.hpp"

#include <cstddef>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "vector_kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace rankslam::robust::vector::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

int RigidScores(const float* sx, const float* sy, const float* sz, const float* dx, const float* dy, const float* dz,
                const Eigen::Matrix3f& r, const Eigen::Vector3f& t, int count, const double* inverse_variances,
                double bound, double* out, int& done) {
  done = 0;
#if HWY_TARGET == HWY_SCALAR
  (void)sx, (void)sy, (void)sz, (void)dx, (void)dy, (void)dz, (void)r, (void)t, (void)count;
  (void)inverse_variances, (void)bound, (void)out;
  return 0;  // one lane: the portable loop does it all
#else
  // Float lanes, each half widened to a vector of doubles.
  const hn::CappedTag<float, 8> d;
  const hn::Half<decltype(d)> dh;
  const hn::Rebind<double, decltype(dh)> dd;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const int half = static_cast<int>(hn::Lanes(dh));
  using V = hn::Vec<decltype(d)>;
  V rotation[9];
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) rotation[3 * row + col] = hn::Set(d, r(row, col));
  }
  const V translation[3] = {hn::Set(d, t.x()), hn::Set(d, t.y()), hn::Set(d, t.z())};
  const auto limit = hn::Set(dd, bound);
  int below = 0;
  int i = 0;
  for (; i + lanes <= count; i += lanes) {
    const V x = hn::LoadU(d, sx + i);
    const V y = hn::LoadU(d, sy + i);
    const V z = hn::LoadU(d, sz + i);
    const float* const target[3] = {dx + i, dy + i, dz + i};
    V sum = hn::Zero(d);
    for (int row = 0; row < 3; ++row) {
      V e = hn::Add(hn::Mul(rotation[3 * row], x), hn::Mul(rotation[3 * row + 1], y));
      e = hn::Add(e, hn::Mul(rotation[3 * row + 2], z));
      e = hn::Add(e, translation[row]);
      e = hn::Sub(e, hn::LoadU(d, target[row]));
      const V square = hn::Mul(e, e);
      sum = row == 0 ? square : hn::Add(sum, square);
    }
    auto low = hn::PromoteTo(dd, hn::LowerHalf(dh, sum));
    auto high = hn::PromoteTo(dd, hn::UpperHalf(dh, sum));
    if (inverse_variances != nullptr) {
      low = hn::Mul(low, hn::LoadU(dd, inverse_variances + i));
      high = hn::Mul(high, hn::LoadU(dd, inverse_variances + i + half));
    }
    hn::StoreU(low, dd, out + i);
    hn::StoreU(high, dd, out + i + half);
    below += static_cast<int>(hn::CountTrue(dd, hn::Lt(low, limit)) + hn::CountTrue(dd, hn::Lt(high, limit)));
  }
  done = i;
  return below;
#endif
}

int OrientationScores(const double* nx, const double* ny, const double* nz, const Eigen::Vector3d& direction,
                      int count, const double* inverse_variances, double bound, double* out, int& done) {
  const hn::CappedTag<double, 4> d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const auto dx = hn::Set(d, direction.x());
  const auto dy = hn::Set(d, direction.y());
  const auto dz = hn::Set(d, direction.z());
  const auto one = hn::Set(d, 1.0);
  const auto limit = hn::Set(d, bound);
  int below = 0;
  int i = 0;
  for (; i + lanes <= count; i += lanes) {
    auto dot = hn::Add(hn::Mul(dx, hn::LoadU(d, nx + i)), hn::Mul(dy, hn::LoadU(d, ny + i)));
    dot = hn::Add(dot, hn::Mul(dz, hn::LoadU(d, nz + i)));
    auto score = hn::Sub(one, dot);
    if (inverse_variances != nullptr) score = hn::Mul(score, hn::LoadU(d, inverse_variances + i));
    hn::StoreU(score, d, out + i);
    below += static_cast<int>(hn::CountTrue(d, hn::Lt(score, limit)));
  }
  done = i;
  return below;
}

}  // namespace rankslam::robust::vector::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace rankslam::robust::vector {

HWY_EXPORT(RigidScores);
HWY_EXPORT(OrientationScores);

int rigid_scores(const float* sx, const float* sy, const float* sz, const float* dx, const float* dy,
                 const float* dz, const Eigen::Matrix3f& r, const Eigen::Vector3f& t, int count,
                 const double* inverse_variances, double bound, double* out, int& done) {
  return HWY_DYNAMIC_DISPATCH(RigidScores)(sx, sy, sz, dx, dy, dz, r, t, count, inverse_variances, bound, out,
                                           done);
}

int orientation_scores(const double* nx, const double* ny, const double* nz, const Eigen::Vector3d& direction,
                       int count, const double* inverse_variances, double bound, double* out, int& done) {
  return HWY_DYNAMIC_DISPATCH(OrientationScores)(nx, ny, nz, direction, count, inverse_variances, bound, out,
                                                 done);
}

}  // namespace rankslam::robust::vector
#endif
