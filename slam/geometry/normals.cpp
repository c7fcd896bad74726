#include "rankslam/geometry/cloud.hpp"

#include "rankslam/parallel/cpu_features.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "vector_kernels.hpp"

// Normals from the block image of the organised depth image: the moments of the blocks inside a
// metric radius around a point, portable 4 blocks at a time or with the vector kernel (up to 8).
namespace rankslam::geometry {

void BlockImage::Layer::reserve(std::size_t blocks) {
  for (std::vector<float>* v : {&x, &y, &z, &weight, &centre_x, &centre_y, &centre_z, &half_x, &half_y, &half_z}) {
    v->assign(blocks, 0.0F);
  }
}

void BlockImage::reserve(int image_width, int image_height) {
  width = (std::max(0, image_width) + kBlock - 1) / kBlock;
  height = (std::max(0, image_height) + kBlock - 1) / kBlock;
  stride = width + kPad;
  const auto n = static_cast<std::size_t>(stride) * static_cast<std::size_t>(height);
  front.reserve(n);
  back.reserve(n);
}

namespace {

// Weighted moments of points relative to the normal's centre.
struct Moments {
  float n = 0.0F;
  float sx = 0.0F, sy = 0.0F, sz = 0.0F;
  float sxx = 0.0F, sxy = 0.0F, sxz = 0.0F, syy = 0.0F, syz = 0.0F, szz = 0.0F;

  void add(const Eigen::Vector3f& d, float w) {
    n += w;
    sx += w * d.x();
    sy += w * d.y();
    sz += w * d.z();
    sxx += w * d.x() * d.x();
    sxy += w * d.x() * d.y();
    sxz += w * d.x() * d.z();
    syy += w * d.y() * d.y();
    syz += w * d.y() * d.z();
    szz += w * d.z() * d.z();
  }
};

// A block's share of a sphere of squared radius r2 around the centre, from the nearest and
// farthest squared distances of its bounding box: 1 inside, 0 outside, in between the share of
// that range inside the radius (a soft boundary about one block wide).
float soft_share(float near2, float far2, float r2) {
  return std::clamp((r2 - near2) / std::max(far2 - near2, 1e-12F), 0.0F, 1.0F);
}

using Lanes = Eigen::Array4f;  // one SSE / NEON register

Lanes soft_share(const Lanes& near2, const Lanes& far2, float r2) {
  return ((r2 - near2) / (far2 - near2).max(1e-12F)).max(0.0F).min(1.0F);
}

// Along one axis, the nearest and farthest distances from 0 to a bounding box's extent with
// centre `centre` (relative to 0) and half extent `half`, squared and added.
EIGEN_ALWAYS_INLINE void extent_range(const Lanes& centre, const Lanes& half, Lanes& near2, Lanes& far2) {
  const Lanes distance = centre.abs();
  const Lanes near = (distance - half).max(0.0F);
  const Lanes far = distance + half;
  near2 += near * near;
  far2 += far * far;
}

// One layer's block b added to the moments by its share of the sphere (the strided window).
inline void add_block(const BlockImage::Layer& layer, std::size_t b, const Eigen::Vector3f& center,
                      float r2, Moments& m) {
  const float w = layer.weight[b];
  if (w == 0.0F) return;
  const Eigen::Vector3f distance =
      (Eigen::Vector3f(layer.centre_x[b], layer.centre_y[b], layer.centre_z[b]) - center).cwiseAbs();
  const Eigen::Vector3f half(layer.half_x[b], layer.half_y[b], layer.half_z[b]);
  const float near2 = (distance - half).cwiseMax(0.0F).squaredNorm();
  if (near2 > r2) return;
  const float far2 = (distance + half).squaredNorm();
  m.add(layer.mean(b) - center, w * soft_share(near2, far2, r2));
}

// The 4 blocks of one layer from block b on, lanes past `valid` weighing nothing, added to the
// lane sums by their shares of the sphere.
struct LaneMoments {
  Lanes n = Lanes::Zero(), sx = Lanes::Zero(), sy = Lanes::Zero(), sz = Lanes::Zero();
  Lanes sxx = Lanes::Zero(), sxy = Lanes::Zero(), sxz = Lanes::Zero(), syy = Lanes::Zero(),
        syz = Lanes::Zero(), szz = Lanes::Zero();

  EIGEN_ALWAYS_INLINE void add(const BlockImage::Layer& layer, std::size_t b, const Eigen::Vector3f& center,
                               float r2, const Lanes& valid) {
    const Lanes w0 = Eigen::Map<const Lanes>(layer.weight.data() + b) * valid;
    const Lanes dx = Eigen::Map<const Lanes>(layer.x.data() + b) - center.x();
    const Lanes dy = Eigen::Map<const Lanes>(layer.y.data() + b) - center.y();
    const Lanes dz = Eigen::Map<const Lanes>(layer.z.data() + b) - center.z();
    Lanes near2 = Lanes::Zero();
    Lanes far2 = Lanes::Zero();
    extent_range(Eigen::Map<const Lanes>(layer.centre_x.data() + b) - center.x(),
                 Eigen::Map<const Lanes>(layer.half_x.data() + b), near2, far2);
    extent_range(Eigen::Map<const Lanes>(layer.centre_y.data() + b) - center.y(),
                 Eigen::Map<const Lanes>(layer.half_y.data() + b), near2, far2);
    extent_range(Eigen::Map<const Lanes>(layer.centre_z.data() + b) - center.z(),
                 Eigen::Map<const Lanes>(layer.half_z.data() + b), near2, far2);
    const Lanes w = w0 * soft_share(near2, far2, r2);
    n += w;
    sx += w * dx;
    sy += w * dy;
    sz += w * dz;
    sxx += w * dx * dx;
    sxy += w * dx * dy;
    sxz += w * dx * dz;
    syy += w * dy * dy;
    syz += w * dy * dz;
    szz += w * dz * dz;
  }

  void add_to(Moments& m) const {
    m.n += n.sum();
    m.sx += sx.sum();
    m.sy += sy.sum();
    m.sz += sz.sum();
    m.sxx += sxx.sum();
    m.sxy += sxy.sum();
    m.sxz += sxz.sum();
    m.syy += syy.sum();
    m.syz += syz.sum();
    m.szz += szz.sum();
  }
};


// Lens distortion changes the pixel footprint of a metric radius by a few per cent over the
// image (fr1's barrel distortion shrinks it toward the corners); the window is widened by this
// factor so that it always covers the radius.
constexpr float kWindowMargin = 1.05F;

}  // namespace

int organised_normal(const BlockImage& blocks, float fx, const Eigen::Vector3f& center,
                     const Eigen::Vector2f& pixel, float radius_m, int samples_per_axis,
                     Eigen::Vector3f& normal, float* curvature, bool best_kernel) {
  if (!(center.z() > 0.0F) || !(radius_m > 0.0F) || samples_per_axis < 1 || blocks.width < 1) {
    return 0;
  }
  constexpr auto kBlockF = static_cast<float>(BlockImage::kBlock);
  const float half_blocks = radius_m * fx / center.z() * kWindowMargin / kBlockF;
  const int stride = std::max(
      1, static_cast<int>(std::lround(2.0F * half_blocks / static_cast<float>(samples_per_axis))));
  const int steps = static_cast<int>(std::ceil(half_blocks)) / stride;
  const int bu = static_cast<int>(pixel.x() / kBlockF);
  const int bv = static_cast<int>(pixel.y() / kBlockF);
  const float r2 = radius_m * radius_m;

  Moments m;
  if (stride == 1 && best_kernel && parallel::vector_kernels_enabled()) {
    float sums[10] = {};
    vector::window_moments(blocks, center, bu, bv, steps, half_blocks, r2, sums);
    m.n = sums[0];
    m.sx = sums[1];
    m.sy = sums[2];
    m.sz = sums[3];
    m.sxx = sums[4];
    m.sxy = sums[5];
    m.sxz = sums[6];
    m.syy = sums[7];
    m.syz = sums[8];
    m.szz = sums[9];
  } else if (stride == 1) {
    // Rows of the window 4 blocks at a time (the rows' padding keeps the reads in bounds).
    const Lanes lane_index(0.0F, 1.0F, 2.0F, 3.0F);
    LaneMoments sums;
    for (int v = std::max(bv - steps, 0); v <= std::min(bv + steps, blocks.height - 1); ++v) {
      int u_lo = 0;
      int u_hi = -1;
      vector::window_row(blocks, bu, bv, half_blocks, v, u_lo, u_hi);
      for (int u = u_lo; u <= u_hi; u += 4) {
        const std::size_t b = blocks.index(u, v);
        const Lanes valid = (lane_index < static_cast<float>(u_hi - u + 1)).cast<float>();
        sums.add(blocks.front, b, center, r2, valid);
        if ((Eigen::Map<const Lanes>(blocks.back.weight.data() + b) * valid > 0.0F).any()) {
          sums.add(blocks.back, b, center, r2, valid);
        }
      }
    }
    sums.add_to(m);
  } else {
    // A near point's wide window: every stride-th block.
    for (int j = -steps; j <= steps; ++j) {
      const int v = bv + j * stride;
      if (v < 0 || v >= blocks.height) continue;
      for (int i = -steps; i <= steps; ++i) {
        const int u = bu + i * stride;
        if (u < 0 || u >= blocks.width) continue;
        const std::size_t b = blocks.index(u, v);
        add_block(blocks.front, b, center, r2, m);
        add_block(blocks.back, b, center, r2, m);
      }
    }
  }
  const int count = static_cast<int>(m.n);
  if (count < 3) return count;
  const Eigen::Vector3f mean = Eigen::Vector3f(m.sx, m.sy, m.sz) / m.n;
  Eigen::Matrix3f cov;
  cov << m.sxx / m.n, m.sxy / m.n, m.sxz / m.n, m.sxy / m.n, m.syy / m.n, m.syz / m.n,
      m.sxz / m.n, m.syz / m.n, m.szz / m.n;
  cov -= mean * mean.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> solver;
  solver.computeDirect(cov);
  Eigen::Vector3f result = solver.eigenvectors().col(0);
  const float length = result.norm();
  if (!(length > 0.0F) || !std::isfinite(length)) return 0;
  result /= length;
  // Toward the camera at the origin: (0 − p)·n > 0.
  if (result.dot(center) > 0.0F) result = -result;
  normal = result;
  if (curvature != nullptr) {
    const float total = solver.eigenvalues().sum();
    *curvature = total > 0.0F ? std::max(0.0F, solver.eigenvalues()(0)) / total : 0.0F;
  }
  return count;
}

}  // namespace rankslam::geometry
