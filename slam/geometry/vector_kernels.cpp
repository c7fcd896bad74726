// The geometry front-end's Highway kernels (vector_kernels.hpp). foreach_target.h compiles this
// file once per vector target; the HWY_ONCE part at the end dispatches to the CPU's best one.
// The project builds with -ffp-contract=off: only the explicit MulAdd fuses, so every other
// product rounds as in the portable loops.
#include "vector_kernels.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "vector_kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace rankslam::geometry::vector::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// At most 8 float lanes on every target: 8 on AVX2 and AVX-512, 4 on SSE4 and NEON.
using D = hn::CappedTag<float, 8>;
using V = hn::Vec<D>;
using M = hn::Mask<D>;
using DI = hn::RebindToSigned<D>;

HWY_INLINE float Sum(D d, V v) { return hn::GetLane(hn::SumOfLanes(d, v)); }

// --- Normals --------------------------------------------------------------------------------

// The blocks of one layer from b on (the lanes of `valid`), each by its share of the sphere of
// squared radius r2 around the centre, added to the moments' lane sums.
HWY_INLINE void AddBlocks(D d, const BlockImage::Layer& layer, std::size_t b, const V (&center)[3], V radius2,
                          M valid, V (&sums)[10]) {
  const V zero = hn::Zero(d);
  const std::array<const float*, 3> mean = {layer.x.data(), layer.y.data(), layer.z.data()};
  const std::array<const float*, 3> centre = {layer.centre_x.data(), layer.centre_y.data(), layer.centre_z.data()};
  const std::array<const float*, 3> half = {layer.half_x.data(), layer.half_y.data(), layer.half_z.data()};
  const V w0 = hn::IfThenElseZero(valid, hn::LoadU(d, layer.weight.data() + b));
  V delta[3];
  V near2 = zero;
  V far2 = zero;
  for (std::size_t axis = 0; axis < 3; ++axis) {
    delta[axis] = hn::Sub(hn::LoadU(d, mean[axis] + b), center[axis]);
    const V distance = hn::Abs(hn::Sub(hn::LoadU(d, centre[axis] + b), center[axis]));
    const V extent = hn::LoadU(d, half[axis] + b);
    const V near = hn::Max(hn::Sub(distance, extent), zero);
    const V far = hn::Add(distance, extent);
    near2 = hn::MulAdd(near, near, near2);
    far2 = hn::MulAdd(far, far, far2);
  }
  // A block's share of the sphere: 1 inside, 0 outside, in between the share of its range of
  // squared distances inside the radius.
  const V share = hn::Min(
      hn::Max(hn::Div(hn::Sub(radius2, near2), hn::Max(hn::Sub(far2, near2), hn::Set(d, 1e-12F))), zero),
      hn::Set(d, 1.0F));
  const V w = hn::Mul(w0, share);
  const V wd[3] = {hn::Mul(w, delta[0]), hn::Mul(w, delta[1]), hn::Mul(w, delta[2])};
  sums[0] = hn::Add(sums[0], w);
  sums[1] = hn::Add(sums[1], wd[0]);
  sums[2] = hn::Add(sums[2], wd[1]);
  sums[3] = hn::Add(sums[3], wd[2]);
  sums[4] = hn::MulAdd(wd[0], delta[0], sums[4]);
  sums[5] = hn::MulAdd(wd[0], delta[1], sums[5]);
  sums[6] = hn::MulAdd(wd[0], delta[2], sums[6]);
  sums[7] = hn::MulAdd(wd[1], delta[1], sums[7]);
  sums[8] = hn::MulAdd(wd[1], delta[2], sums[8]);
  sums[9] = hn::MulAdd(wd[2], delta[2], sums[9]);
}

// A vector's worth of blocks of a window row from `block` on, the first `lanes` of them inside
// the window.
struct WindowGroup {
  std::int32_t block;
  float lanes;
};

// The groups' blocks of both layers added to the lane sums, in order.
HWY_INLINE void SumWindowGroups(D d, const BlockImage& blocks, const WindowGroup* groups, int count,
                                const V (&center)[3], V radius2, V (&sums)[10]) {
  const V lane_index = hn::Iota(d, 0.0F);
  for (int g = 0; g < count; ++g) {
    const auto b = static_cast<std::size_t>(groups[g].block);
    const M valid = hn::Lt(lane_index, hn::Set(d, groups[g].lanes));
    AddBlocks(d, blocks.front, b, center, radius2, valid, sums);
    const V back = hn::IfThenElseZero(valid, hn::LoadU(d, blocks.back.weight.data() + b));
    if (!hn::AllFalse(d, hn::Gt(back, hn::Zero(d)))) AddBlocks(d, blocks.back, b, center, radius2, valid, sums);
  }
}

void WindowMoments(const BlockImage& blocks, const Eigen::Vector3f& center, int bu, int bv, int steps,
                   float half_blocks, float r2, float (&out)[10]) {
  const D d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const V radius2 = hn::Set(d, r2);
  const V c[3] = {hn::Set(d, center.x()), hn::Set(d, center.y()), hn::Set(d, center.z())};
  V sums[10];
  for (V& sum : sums) sum = hn::Zero(d);
  // The window's groups are listed first (rows ascending, then columns), then summed in one loop:
  // the rows' varying group counts would otherwise end each row's loop on a mispredicted branch
  // in the middle of the vector work.
  constexpr int kMaxGroups = 64;
  std::array<WindowGroup, kMaxGroups> groups;
  int listed = 0;
  // The rows' padding keeps the reads in bounds.
  for (int v = std::max(bv - steps, 0); v <= std::min(bv + steps, blocks.height - 1); ++v) {
    int u_lo = 0;
    int u_hi = -1;
    window_row(blocks, bu, bv, half_blocks, v, u_lo, u_hi);
    for (int u = u_lo; u <= u_hi; u += lanes) {
      if (listed == kMaxGroups) {
        SumWindowGroups(d, blocks, groups.data(), listed, c, radius2, sums);
        listed = 0;
      }
      groups[static_cast<std::size_t>(listed++)] =
          WindowGroup{static_cast<std::int32_t>(blocks.index(u, v)), static_cast<float>(u_hi - u + 1)};
    }
  }
  SumWindowGroups(d, blocks, groups.data(), listed, c, radius2, sums);
  for (std::size_t k = 0; k < 10; ++k) out[k] += Sum(d, sums[k]);
}

// --- SHOT votes -----------------------------------------------------------------------------

HWY_INLINE V Clamp(D d, V a, float lo, float hi) { return hn::Min(hn::Max(a, hn::Set(d, lo)), hn::Set(d, hi)); }
// Three products added left to right, each rounded: the portable loop's a·x + b·y + c·z.
HWY_INLINE V Dot(D d, V a, V b, V c, const Eigen::Vector3f& axis) {
  return hn::Add(hn::Add(hn::Mul(a, hn::Set(d, axis.x())), hn::Mul(b, hn::Set(d, axis.y()))),
                 hn::Mul(c, hn::Set(d, axis.z())));
}
HWY_INLINE V Ones(D d, M m) { return hn::IfThenElseZero(m, hn::Set(d, 1.0F)); }
// Bins held as exact small integers in floats, stored as integers.
HWY_INLINE void StoreBins(D d, std::int32_t* to, V bins) {
  const hn::RebindToSigned<decltype(d)> di;
  hn::StoreU(hn::ConvertTo(di, bins), di, to);
}

void ShotVoteBins(const VoteArrays& v, const VoteFrame& f, int end) {
  const D d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  using C = VoteConstants;
  const V zero = hn::Zero(d);
  const V one = hn::Set(d, 1.0F);
  const V r14 = hn::Set(d, f.radius_1_4);
  const V r12 = hn::Set(d, f.radius_1_2);
  const V r34 = hn::Set(d, f.radius_3_4);
  const V inverse_r12 = hn::Set(d, 1.0F / f.radius_1_2);
  for (int k = 0; k < end; k += lanes) {
    const V dx = hn::LoadU(d, v.dx + k);
    const V dy = hn::LoadU(d, v.dy + k);
    const V dz = hn::LoadU(d, v.dz + k);
    const V distance = hn::LoadU(d, v.distance + k);
    const V x = Dot(d, dx, dy, dz, f.x);
    const V y = Dot(d, dx, dy, dz, f.y);
    const V z = Dot(d, dx, dy, dz, f.z);
    const V cosine = Clamp(d, Dot(d, hn::LoadU(d, v.nx + k), hn::LoadU(d, v.ny + k), hn::LoadU(d, v.nz + k), f.z),
                           -1.0F, 1.0F);

    // Volume: azimuth octant (bits 4, 3 and the diagonal split), elevation (z > 0), radius.
    const M y_positive = hn::Gt(y, zero);
    const M x_zero = hn::Eq(x, zero);
    const V bit4 = Ones(d, hn::Or(y_positive, hn::And(hn::Eq(y, zero), hn::Lt(x, zero))));
    const M flip = hn::Or(hn::Gt(x, zero), hn::And(x_zero, y_positive));
    const V bit3 = hn::IfThenElse(flip, hn::Sub(one, bit4), bit4);
    const V ax = hn::Abs(x);
    const V ay = hn::Abs(y);
    const M same_sign = hn::Or(hn::Gt(hn::Mul(x, y), zero), x_zero);
    const V diagonal = hn::IfThenElse(same_sign, Ones(d, hn::Lt(ax, ay)), Ones(d, hn::Gt(ax, ay)));
    const V sector = hn::Add(hn::Add(hn::Mul(hn::Set(d, 4.0F), bit4), hn::Mul(hn::Set(d, 2.0F), bit3)), diagonal);
    const M outer = hn::Gt(distance, r12);
    const V volume = hn::Add(hn::Add(hn::Mul(hn::Set(d, 4.0F), sector), Ones(d, hn::Gt(z, zero))),
                             hn::IfThenElseZero(outer, hn::Set(d, 2.0F)));

    // Cosine bin and the adjacent one, circular over the bins.
    const V bin = hn::Mul(hn::Add(one, cosine), hn::Set(d, 0.5F * C::kBins));
    const V step = hn::ConvertTo(d, hn::ConvertTo(DI(), hn::Add(bin, hn::Set(d, 0.5F))));
    const V volume_base = hn::Mul(volume, hn::Set(d, C::kStride));
    const V own = hn::Add(volume_base, step);
    const V bin_distance = hn::Sub(bin, step);
    V weight = hn::Sub(one, hn::Abs(bin_distance));
    const V next_raw = hn::Add(step, one);
    const V next = hn::Sub(next_raw, hn::IfThenElseZero(hn::Ge(next_raw, hn::Set(d, C::kBins)), hn::Set(d, C::kBins)));
    const V previous_raw = hn::Add(step, hn::Set(d, C::kBins - 1.0F));
    const V previous =
        hn::Sub(previous_raw, hn::IfThenElseZero(hn::Ge(previous_raw, hn::Set(d, C::kBins)), hn::Set(d, C::kBins)));
    StoreBins(d, v.cosine + k, hn::Add(volume_base, hn::IfThenElse(hn::Gt(bin_distance, zero), next, previous)));
    hn::StoreU(hn::Abs(bin_distance), d, v.cosine_weight + k);

    // Radial shell: the outer one votes inward below 3R/4, the inner one outward above R/4.
    const V radius_distance = hn::Mul(hn::Sub(distance, hn::IfThenElse(outer, r34, r14)), inverse_r12);
    weight = hn::Add(weight, hn::Sub(one, hn::Abs(radius_distance)));
    const M radial_vote =
        hn::Or(hn::And(outer, hn::Le(radius_distance, zero)), hn::AndNot(outer, hn::Ge(radius_distance, zero)));
    StoreBins(d, v.radial + k,
              hn::Add(own, hn::IfThenElseZero(radial_vote, hn::IfThenElse(outer, hn::Set(d, -2.0F * C::kStride),
                                                                          hn::Set(d, 2.0F * C::kStride)))));
    hn::StoreU(hn::IfThenElseZero(radial_vote, hn::Abs(radius_distance)), d, v.radial_weight + k);

    // Elevation: the lower volume votes up below 135°, the upper one down above 45°.
    const V cz = Clamp(d, hn::Div(z, distance), -1.0F, 1.0F);
    const V ac = hn::Abs(cz);
    V poly = hn::Set(d, -0.0012624911F);
    for (const float coefficient : {0.0066700901F, -0.0170881256F, 0.0308918810F, -0.0501743046F, 0.0889789874F,
                                    -0.2145988016F, 1.5707963050F}) {
      poly = hn::Add(hn::Set(d, coefficient), hn::Mul(ac, poly));
    }
    const V arc = hn::Mul(hn::Sqrt(hn::Sub(one, ac)), poly);
    const V inclination = hn::IfThenElse(hn::Ge(cz, zero), arc, hn::Sub(hn::Set(d, C::kPi), arc));
    const M lower = hn::Or(hn::Gt(inclination, hn::Set(d, C::kRad90)),
                           hn::And(hn::Eq(inclination, hn::Set(d, C::kRad90)), hn::Le(z, zero)));
    const V inclination_distance =
        hn::Mul(hn::Sub(inclination, hn::IfThenElse(lower, hn::Set(d, C::kRad135), hn::Set(d, C::kRad45))),
                hn::Set(d, 1.0F / C::kRad90));
    weight = hn::Add(weight, hn::Sub(one, hn::Abs(inclination_distance)));
    const M elevation_vote = hn::Or(hn::And(lower, hn::Le(inclination_distance, zero)),
                                    hn::AndNot(lower, hn::Ge(inclination_distance, zero)));
    StoreBins(d, v.elevation + k,
              hn::Add(own, hn::IfThenElseZero(elevation_vote,
                                              hn::IfThenElse(lower, hn::Set(d, C::kStride), hn::Set(d, -C::kStride)))));
    hn::StoreU(hn::IfThenElseZero(elevation_vote, hn::Abs(inclination_distance)), d, v.elevation_weight + k);

    // Azimuth: adjacent sectors, circular; undefined on the LRF's z axis.
    const M defined = hn::Or(hn::Ne(y, zero), hn::Ne(x, zero));
    const V t = hn::Div(hn::Min(ax, ay), hn::IfThenElse(defined, hn::Max(ax, ay), one));
    const V t2 = hn::Mul(t, t);
    V series = hn::Set(d, -0.01172120F);
    for (const float coefficient : {0.05265332F, -0.11643287F, 0.19354346F, -0.33262347F, 0.99997726F}) {
      series = hn::Add(hn::Set(d, coefficient), hn::Mul(t2, series));
    }
    V azimuth = hn::Mul(t, series);
    azimuth = hn::IfThenElse(hn::Gt(ay, ax), hn::Sub(hn::Set(d, 0.5F * C::kPi), azimuth), azimuth);
    azimuth = hn::IfThenElse(hn::Lt(x, zero), hn::Sub(hn::Set(d, C::kPi), azimuth), azimuth);
    azimuth = hn::IfThenElse(hn::Lt(y, zero), hn::Sub(zero, azimuth), azimuth);
    const V azimuth_distance = Clamp(
        d,
        hn::Mul(hn::Sub(azimuth, hn::Add(hn::Set(d, -C::kRadPi78), hn::Mul(hn::Set(d, C::kRad45), sector))),
                hn::Set(d, 1.0F / C::kRad45)),
        -0.5F, 0.5F);
    weight = hn::Add(weight, hn::IfThenElseZero(defined, hn::Sub(one, hn::Abs(azimuth_distance))));
    V adjacent = hn::Add(volume, hn::IfThenElse(hn::Gt(azimuth_distance, zero), hn::Set(d, 4.0F),
                                                hn::Set(d, C::kVolumes - 4.0F)));
    adjacent = hn::Sub(adjacent, hn::IfThenElseZero(hn::Ge(adjacent, hn::Set(d, C::kVolumes)), hn::Set(d, C::kVolumes)));
    StoreBins(d, v.azimuth + k, hn::Add(hn::Mul(adjacent, hn::Set(d, C::kStride)), step));
    hn::StoreU(hn::IfThenElseZero(defined, hn::Abs(azimuth_distance)), d, v.azimuth_weight + k);

    StoreBins(d, v.own + k, own);
    hn::StoreU(weight, d, v.own_weight + k);
  }
}

// --- Descriptor matching --------------------------------------------------------------------

float DotInLanes(const float* x, const float* y, int dim) {
  const D d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const int vector_end = dim - dim % lanes;
  V s = hn::Zero(d);
  for (int k = 0; k < vector_end; k += lanes) s = hn::MulAdd(hn::LoadU(d, x + k), hn::LoadU(d, y + k), s);
  return Sum(d, s) + dot_in_sequence(x, y, dim, vector_end);
}

// 4 × 3 blocks: 12 accumulators, 3 rows of B and one of A in registers (16 of AVX2's 16), so
// that each step loads 7 vectors for 12 multiply-adds.
void ScanDotProducts(const float* a, int na, const float* b, int nb, int dim, Best& best) {
  const D d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const int vector_end = dim - dim % lanes;
  const auto row = [dim](const float* base, int index) { return base + static_cast<std::ptrdiff_t>(index) * dim; };
  int i = 0;
  for (; i + 3 < na; i += 4) {
    const float* a0 = row(a, i);
    const float* a1 = a0 + dim;
    const float* a2 = a1 + dim;
    const float* a3 = a2 + dim;
    int j = 0;
    for (; j + 2 < nb; j += 3) {
      const float* b0 = row(b, j);
      const float* b1 = b0 + dim;
      const float* b2 = b1 + dim;
      V s00 = hn::Zero(d), s01 = hn::Zero(d), s02 = hn::Zero(d);
      V s10 = hn::Zero(d), s11 = hn::Zero(d), s12 = hn::Zero(d);
      V s20 = hn::Zero(d), s21 = hn::Zero(d), s22 = hn::Zero(d);
      V s30 = hn::Zero(d), s31 = hn::Zero(d), s32 = hn::Zero(d);
      for (int k = 0; k < vector_end; k += lanes) {
        const V y0 = hn::LoadU(d, b0 + k);
        const V y1 = hn::LoadU(d, b1 + k);
        const V y2 = hn::LoadU(d, b2 + k);
        V x = hn::LoadU(d, a0 + k);
        s00 = hn::MulAdd(x, y0, s00);
        s01 = hn::MulAdd(x, y1, s01);
        s02 = hn::MulAdd(x, y2, s02);
        x = hn::LoadU(d, a1 + k);
        s10 = hn::MulAdd(x, y0, s10);
        s11 = hn::MulAdd(x, y1, s11);
        s12 = hn::MulAdd(x, y2, s12);
        x = hn::LoadU(d, a2 + k);
        s20 = hn::MulAdd(x, y0, s20);
        s21 = hn::MulAdd(x, y1, s21);
        s22 = hn::MulAdd(x, y2, s22);
        x = hn::LoadU(d, a3 + k);
        s30 = hn::MulAdd(x, y0, s30);
        s31 = hn::MulAdd(x, y1, s31);
        s32 = hn::MulAdd(x, y2, s32);
      }
      update(best, i, j, Sum(d, s00) + dot_in_sequence(a0, b0, dim, vector_end));
      update(best, i, j + 1, Sum(d, s01) + dot_in_sequence(a0, b1, dim, vector_end));
      update(best, i, j + 2, Sum(d, s02) + dot_in_sequence(a0, b2, dim, vector_end));
      update(best, i + 1, j, Sum(d, s10) + dot_in_sequence(a1, b0, dim, vector_end));
      update(best, i + 1, j + 1, Sum(d, s11) + dot_in_sequence(a1, b1, dim, vector_end));
      update(best, i + 1, j + 2, Sum(d, s12) + dot_in_sequence(a1, b2, dim, vector_end));
      update(best, i + 2, j, Sum(d, s20) + dot_in_sequence(a2, b0, dim, vector_end));
      update(best, i + 2, j + 1, Sum(d, s21) + dot_in_sequence(a2, b1, dim, vector_end));
      update(best, i + 2, j + 2, Sum(d, s22) + dot_in_sequence(a2, b2, dim, vector_end));
      update(best, i + 3, j, Sum(d, s30) + dot_in_sequence(a3, b0, dim, vector_end));
      update(best, i + 3, j + 1, Sum(d, s31) + dot_in_sequence(a3, b1, dim, vector_end));
      update(best, i + 3, j + 2, Sum(d, s32) + dot_in_sequence(a3, b2, dim, vector_end));
    }
    for (; j < nb; ++j) {
      const float* b0 = row(b, j);
      for (int r = 0; r < 4; ++r) update(best, i + r, j, dot_in_sequence(a0 + static_cast<std::ptrdiff_t>(r) * dim, b0, dim));
    }
  }
  for (; i < na; ++i) {
    const float* a0 = row(a, i);
    for (int j = 0; j < nb; ++j) update(best, i, j, DotInLanes(a0, row(b, j), dim));
  }
}


// --- Cloud pre-processing -------------------------------------------------------------------

int PrepareRow(const std::uint16_t* raw, const float* ray_x, const float* ray_y, int width, float metres_per_unit,
               float min_m, float max_m, float inverse_leaf, const RowPoints& out) {
  const D d;
  const DI di;
  const hn::Rebind<std::uint16_t, D> du16;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const V scale = hn::Set(d, metres_per_unit);
  const V lo = hn::Set(d, min_m);
  const V hi = hn::Set(d, max_m);
  const V inverse = hn::Set(d, inverse_leaf);
  const V zero = hn::Zero(d);
  const auto cell = [&](V value, M valid) {
    return hn::IfThenElseZero(hn::RebindMask(di, valid), hn::ConvertTo(di, hn::Floor(hn::Mul(value, inverse))));
  };
  int u = 0;
  for (; u + lanes <= width; u += lanes) {
    const V raw_f = hn::ConvertTo(d, hn::PromoteTo(di, hn::LoadU(du16, raw + u)));
    const V z = hn::Mul(raw_f, scale);
    const M valid = hn::And(hn::Ne(raw_f, zero), hn::And(hn::Ge(z, lo), hn::Le(z, hi)));
    const V x = hn::Mul(hn::LoadU(d, ray_x + u), z);
    const V y = hn::Mul(hn::LoadU(d, ray_y + u), z);
    hn::StoreU(x, d, out.x + u);
    hn::StoreU(y, d, out.y + u);
    hn::StoreU(hn::IfThenElseZero(valid, z), d, out.z + u);
    hn::StoreU(cell(x, valid), di, out.cell_x + u);
    hn::StoreU(cell(y, valid), di, out.cell_y + u);
    hn::StoreU(cell(z, valid), di, out.cell_z + u);
  }
  return u;
}

int AddBlockRows(const float* x, const float* y, const float* z, int blocks, float* sum_x, float* sum_y,
                 float* sum_z, float* min_x, float* min_y, float* min_z, float* max_x, float* max_y, float* max_z,
                 std::int32_t* count) {
  static_assert(BlockImage::kBlock == 4, "the blocks' pixels are de-interleaved 4 at a time");
  const D d;
  const DI di;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const V zero = hn::Zero(d);
  const V infinity = hn::Inf(d);
  const V minus_infinity = hn::Neg(infinity);
  const hn::Vec<DI> one = hn::Set(di, 1);
  int b = 0;
  for (; b + lanes <= blocks; b += lanes) {
    const int first_pixel = b * BlockImage::kBlock;
    // Vector c holds pixel c of each block, blocks in order.
    V px[4], py[4], pz[4];
    hn::LoadInterleaved4(d, x + first_pixel, px[0], px[1], px[2], px[3]);
    hn::LoadInterleaved4(d, y + first_pixel, py[0], py[1], py[2], py[3]);
    hn::LoadInterleaved4(d, z + first_pixel, pz[0], pz[1], pz[2], pz[3]);
    V sx = hn::LoadU(d, sum_x + b), sy = hn::LoadU(d, sum_y + b), sz = hn::LoadU(d, sum_z + b);
    V lx = hn::LoadU(d, min_x + b), ly = hn::LoadU(d, min_y + b), lz = hn::LoadU(d, min_z + b);
    V hx = hn::LoadU(d, max_x + b), hy = hn::LoadU(d, max_y + b), hz = hn::LoadU(d, max_z + b);
    hn::Vec<DI> n = hn::LoadU(di, count + b);
    for (std::size_t c = 0; c < 4; ++c) {
      const M valid = hn::Gt(pz[c], zero);
      sx = hn::Add(sx, hn::IfThenElseZero(valid, px[c]));
      sy = hn::Add(sy, hn::IfThenElseZero(valid, py[c]));
      sz = hn::Add(sz, hn::IfThenElseZero(valid, pz[c]));
      lx = hn::Min(lx, hn::IfThenElse(valid, px[c], infinity));
      ly = hn::Min(ly, hn::IfThenElse(valid, py[c], infinity));
      lz = hn::Min(lz, hn::IfThenElse(valid, pz[c], infinity));
      hx = hn::Max(hx, hn::IfThenElse(valid, px[c], minus_infinity));
      hy = hn::Max(hy, hn::IfThenElse(valid, py[c], minus_infinity));
      hz = hn::Max(hz, hn::IfThenElse(valid, pz[c], minus_infinity));
      n = hn::Add(n, hn::IfThenElseZero(hn::RebindMask(di, valid), one));
    }
    hn::StoreU(sx, d, sum_x + b);
    hn::StoreU(sy, d, sum_y + b);
    hn::StoreU(sz, d, sum_z + b);
    hn::StoreU(lx, d, min_x + b);
    hn::StoreU(ly, d, min_y + b);
    hn::StoreU(lz, d, min_z + b);
    hn::StoreU(hx, d, max_x + b);
    hn::StoreU(hy, d, max_y + b);
    hn::StoreU(hz, d, max_z + b);
    hn::StoreU(n, di, count + b);
  }
  return b;
}

// --- Point grid -----------------------------------------------------------------------------

// The offsets p − q of a vector of points and their squared distances, x² + (y² + z²) as
// Eigen's squaredNorm of a 3-vector sums it.
struct Offsets {
  V dx, dy, dz, d2;
};
HWY_INLINE Offsets OffsetsOf(D d, const float* xs, const float* ys, const float* zs, V qx, V qy, V qz) {
  Offsets o{hn::Sub(hn::LoadU(d, xs), qx), hn::Sub(hn::LoadU(d, ys), qy), hn::Sub(hn::LoadU(d, zs), qz), hn::Zero(d)};
  o.d2 = hn::Add(hn::Mul(o.dx, o.dx), hn::Add(hn::Mul(o.dy, o.dy), hn::Mul(o.dz, o.dz)));
  return o;
}

int WithinRadius(const float* xs, const float* ys, const float* zs, const int* indices, const Eigen::Vector3f& q,
                 float r2, int count, int* hits, float* hit_d2, int& done) {
  const D d;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const V qx = hn::Set(d, q.x());
  const V qy = hn::Set(d, q.y());
  const V qz = hn::Set(d, q.z());
  const V limit = hn::Set(d, r2);
  HWY_ALIGN float d2[8];
  int found = 0;
  int k = 0;
  for (; k + lanes <= count; k += lanes) {
    const V sum = OffsetsOf(d, xs + k, ys + k, zs + k, qx, qy, qz).d2;
    const M inside = hn::Le(sum, limit);
    if (hn::AllFalse(d, inside)) continue;
    hn::Store(sum, d, d2);
    for (int lane = 0; lane < lanes; ++lane) {
      if (!(d2[lane] <= r2)) continue;
      hits[found] = indices[k + lane];
      hit_d2[found] = d2[lane];
      ++found;
    }
  }
  done = k;
  return found;
}

void GatherRun(const float* xs, const float* ys, const float* zs, const int* indices, const Eigen::Vector3f& q,
               float r2, int count, const PointGrid::RadiusGather& out, int& written, int& support) {
  const D d;
  const DI di;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const V qx = hn::Set(d, q.x());
  const V qy = hn::Set(d, q.y());
  const V qz = hn::Set(d, q.z());
  const V limit = hn::Set(d, r2);
  const hn::Vec<DI> lane_index = hn::Iota(di, 0);
  for (int k = 0; k < count; k += lanes) {
    const Offsets o = OffsetsOf(d, xs + k, ys + k, zs + k, qx, qy, qz);
    const M in_run = hn::RebindMask(d, hn::Lt(lane_index, hn::Set(di, count - k)));
    const M inside = hn::And(in_run, hn::Le(o.d2, limit));
    const auto inside_count = static_cast<int>(hn::CountTrue(d, inside));
    if (inside_count == 0) continue;
    support += inside_count;
    const M keep = hn::And(inside, hn::Ne(o.d2, hn::Zero(d)));
    if (hn::AllFalse(d, keep)) continue;
    const int at = written;
    hn::CompressStore(o.dx, keep, d, out.dx + at);
    hn::CompressStore(o.dy, keep, d, out.dy + at);
    hn::CompressStore(o.dz, keep, d, out.dz + at);
    hn::CompressStore(o.d2, keep, d, out.d2 + at);
    const auto kept = static_cast<int>(
        hn::CompressStore(hn::LoadU(di, indices + k), hn::RebindMask(di, keep), di, out.index + at));
    written = std::min(at + kept, out.capacity);
  }
}

// --- Binary descriptors ----------------------------------------------------------------------

int HammingScan(const std::uint64_t* source, int n_source, const std::uint64_t* planes, int stride, int end,
                std::int64_t* row_best, std::int64_t* row_arg, std::int64_t* col_best, std::int64_t* col_arg) {
#if HWY_TARGET == HWY_SCALAR
  (void)source, (void)n_source, (void)planes, (void)stride, (void)end;
  (void)row_best, (void)row_arg, (void)col_best, (void)col_arg;
  return 0;  // one lane: the portable loop does it all
#else
  // One source against a vector of targets: each lane a target's distance, the bytes' counts of
  // the four words added (at most 32 per byte) before one sum per lane.
  const hn::CappedTag<std::int64_t, 8> d;
  const hn::RebindToUnsigned<decltype(d)> du;
  const hn::Repartition<std::uint8_t, decltype(d)> d8;
  using VI = hn::Vec<decltype(d)>;
  const int lanes = static_cast<int>(hn::Lanes(d));
  const int done = end - end % lanes;
  if (done == 0) return 0;
  HWY_ALIGN std::int64_t lane_best[8];
  HWY_ALIGN std::int64_t lane_arg[8];
  const std::ptrdiff_t plane = stride;
  for (int i = 0; i < n_source; ++i) {
    const std::uint64_t* a = source + 4 * static_cast<std::ptrdiff_t>(i);
    const auto a0 = hn::Set(du, a[0]);
    const auto a1 = hn::Set(du, a[1]);
    const auto a2 = hn::Set(du, a[2]);
    const auto a3 = hn::Set(du, a[3]);
    const VI row = hn::Set(d, static_cast<std::int64_t>(i));
    VI best = hn::Set(d, std::numeric_limits<std::int64_t>::max());
    VI arg = hn::Zero(d);
    for (int j = 0; j < done; j += lanes) {
      const std::uint64_t* b = planes + j;
      auto count = hn::PopulationCount(hn::BitCast(d8, hn::Xor(a0, hn::LoadU(du, b))));
      count = hn::Add(count, hn::PopulationCount(hn::BitCast(d8, hn::Xor(a1, hn::LoadU(du, b + plane)))));
      count = hn::Add(count, hn::PopulationCount(hn::BitCast(d8, hn::Xor(a2, hn::LoadU(du, b + 2 * plane)))));
      count = hn::Add(count, hn::PopulationCount(hn::BitCast(d8, hn::Xor(a3, hn::LoadU(du, b + 3 * plane)))));
      const VI distance = hn::BitCast(d, hn::SumsOf8(count));
      const auto nearer = hn::Lt(distance, best);
      best = hn::IfThenElse(nearer, distance, best);
      arg = hn::IfThenElse(nearer, hn::Iota(d, static_cast<std::int64_t>(j)), arg);
      const VI column = hn::LoadU(d, col_best + j);
      const auto nearer_column = hn::Lt(distance, column);
      hn::StoreU(hn::IfThenElse(nearer_column, distance, column), d, col_best + j);
      hn::StoreU(hn::IfThenElse(nearer_column, row, hn::LoadU(d, col_arg + j)), d, col_arg + j);
    }
    // Each lane holds its targets' nearest, the lowest index on ties: the lanes' nearest, ties
    // to the lowest index, is the row's.
    hn::Store(best, d, lane_best);
    hn::Store(arg, d, lane_arg);
    std::int64_t nearest = lane_best[0];
    std::int64_t nearest_arg = lane_arg[0];
    for (int lane = 1; lane < lanes; ++lane) {
      if (lane_best[lane] < nearest || (lane_best[lane] == nearest && lane_arg[lane] < nearest_arg)) {
        nearest = lane_best[lane];
        nearest_arg = lane_arg[lane];
      }
    }
    row_best[i] = nearest;
    row_arg[i] = nearest_arg;
  }
  return done;
#endif
}

}  // namespace rankslam::geometry::vector::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace rankslam::geometry::vector {

HWY_EXPORT(WindowMoments);
HWY_EXPORT(ShotVoteBins);
HWY_EXPORT(ScanDotProducts);
HWY_EXPORT(DotInLanes);
HWY_EXPORT(PrepareRow);
HWY_EXPORT(AddBlockRows);
HWY_EXPORT(WithinRadius);
HWY_EXPORT(GatherRun);
HWY_EXPORT(HammingScan);

void window_moments(const BlockImage& blocks, const Eigen::Vector3f& center, int bu, int bv, int steps,
                    float half_blocks, float r2, float (&sums)[10]) {
  HWY_DYNAMIC_DISPATCH(WindowMoments)(blocks, center, bu, bv, steps, half_blocks, r2, sums);
}

void shot_vote_bins(const VoteArrays& v, const VoteFrame& f, int end) {
  HWY_DYNAMIC_DISPATCH(ShotVoteBins)(v, f, end);
}

void scan_dot_products(const float* a, int na, const float* b, int nb, int dim, Best& best) {
  HWY_DYNAMIC_DISPATCH(ScanDotProducts)(a, na, b, nb, dim, best);
}

float dot_in_lanes(const float* x, const float* y, int dim) { return HWY_DYNAMIC_DISPATCH(DotInLanes)(x, y, dim); }

int prepare_row(const std::uint16_t* raw, const float* ray_x, const float* ray_y, int width,
                float metres_per_unit, float min_m, float max_m, float inverse_leaf, const RowPoints& out) {
  return HWY_DYNAMIC_DISPATCH(PrepareRow)(raw, ray_x, ray_y, width, metres_per_unit, min_m, max_m, inverse_leaf, out);
}

int add_block_rows(const float* x, const float* y, const float* z, int blocks, float* sum_x, float* sum_y,
                   float* sum_z, float* min_x, float* min_y, float* min_z, float* max_x, float* max_y,
                   float* max_z, std::int32_t* count) {
  return HWY_DYNAMIC_DISPATCH(AddBlockRows)(x, y, z, blocks, sum_x, sum_y, sum_z, min_x, min_y, min_z, max_x,
                                            max_y, max_z, count);
}

int within_radius(const float* xs, const float* ys, const float* zs, const int* indices, const Eigen::Vector3f& q,
                  float r2, int count, int* hits, float* hit_d2, int& done) {
  return HWY_DYNAMIC_DISPATCH(WithinRadius)(xs, ys, zs, indices, q, r2, count, hits, hit_d2, done);
}

void gather_run(const float* xs, const float* ys, const float* zs, const int* indices, const Eigen::Vector3f& q,
                float r2, int count, const PointGrid::RadiusGather& out, int& written, int& support) {
  HWY_DYNAMIC_DISPATCH(GatherRun)(xs, ys, zs, indices, q, r2, count, out, written, support);
}

int hamming_scan(const std::uint64_t* source, int n_source, const std::uint64_t* planes, int stride, int end,
                 std::int64_t* row_best, std::int64_t* row_arg, std::int64_t* col_best, std::int64_t* col_arg) {
  return HWY_DYNAMIC_DISPATCH(HammingScan)(source, n_source, planes, stride, end, row_best, row_arg, col_best,
                                           col_arg);
}

}  // namespace rankslam::geometry::vector
#endif
