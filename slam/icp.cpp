#include "rankslam/slam/icp.hpp"

#include "rankslam/robust/rigid.hpp"

#include <nanoflann.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

namespace rankslam::slam {

namespace {

// nanoflann reads the target cloud through this adaptor.
struct CloudAdaptor {
  const std::vector<Eigen::Vector3f>* points = nullptr;

  [[nodiscard]] std::size_t kdtree_get_point_count() const { return points == nullptr ? 0 : points->size(); }
  [[nodiscard]] float kdtree_get_pt(std::size_t index, std::size_t dim) const {
    return (*points)[index][static_cast<Eigen::Index>(dim)];
  }
  template <class BoundingBox>
  bool kdtree_get_bbox(BoundingBox& /*box*/) const {
    return false;
  }
};

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>, CloudAdaptor, 3,
                                                   std::uint32_t>;

// Normals come from central differences this many pixels apart: Kinect depth is quantised in
// steps of about 1 % of the depth at 2 m, so neighbours closer than a few pixels give normals
// dominated by the steps.
constexpr int kNormalSpan = 4;

constexpr std::int64_t kEmptyKey = std::numeric_limits<std::int64_t>::min();

// 21 bits per axis: ±10 km at 2 cm voxels, far beyond any depth camera.
std::int64_t voxel_key(int x, int y, int z) {
  constexpr std::int64_t kOffset = 1 << 20;
  return ((static_cast<std::int64_t>(x) + kOffset) << 42) | ((static_cast<std::int64_t>(y) + kOffset) << 21) |
         (static_cast<std::int64_t>(z) + kOffset);
}

std::size_t hash_key(std::int64_t key) {
  auto h = static_cast<std::uint64_t>(key);
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdULL;
  h ^= h >> 33;
  return static_cast<std::size_t>(h);
}

Eigen::Matrix3d exp_rotation(const Eigen::Vector3d& rotation) {
  const double angle = rotation.norm();
  return angle > 0.0 ? Eigen::AngleAxisd(angle, rotation / angle).toRotationMatrix() : Eigen::Matrix3d::Identity();
}

}  // namespace

struct IcpRefiner::Impl {
  struct Voxel {
    std::int64_t key = kEmptyKey;
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    Eigen::Vector3f normal_sum = Eigen::Vector3f::Zero();
    std::uint32_t count = 0;
  };

  explicit Impl(std::size_t max_points)
      : table(std::bit_ceil(std::max<std::size_t>(2 * max_points, 16))),
        mask(table.size() - 1),
        tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10, nanoflann::KDTreeSingleIndexAdaptorFlags::SkipInitialBuildIndex)),
        pair_source(3, static_cast<Eigen::Index>(max_points)),
        pair_target(3, static_cast<Eigen::Index>(max_points)) {
    used.reserve(max_points);
  }

  std::vector<Voxel> table;
  std::size_t mask;
  std::vector<std::size_t> used;
  CloudAdaptor adaptor;
  KdTree tree;
  const VoxelCloud* target = nullptr;
  std::int64_t target_key = std::numeric_limits<std::int64_t>::min();
  Eigen::Matrix3Xd pair_source;
  Eigen::Matrix3Xd pair_target;
};

IcpRefiner::IcpRefiner(const IcpSettings& settings, const camera::DepthCameraModel& camera)
    : settings_(settings), camera_(camera), impl_(std::make_unique<Impl>(cloud_capacity())) {}

IcpRefiner::~IcpRefiner() = default;

std::size_t IcpRefiner::cloud_capacity() const {
  const auto stride = static_cast<std::size_t>(std::max(1, settings_.pixel_stride));
  return (static_cast<std::size_t>(camera_.width()) / stride + 1) * (static_cast<std::size_t>(camera_.height()) / stride + 1);
}

void IcpRefiner::build_cloud(const cv::Mat& depth, VoxelCloud& cloud) {
  Impl& impl = *impl_;
  for (const std::size_t slot : impl.used) impl.table[slot] = Impl::Voxel{};
  impl.used.clear();
  cloud.points.clear();
  cloud.normals.clear();
  if (depth.type() != CV_16UC1 || depth.cols != camera_.width() || depth.rows != camera_.height()) return;

  const bool want_normals = settings_.mode == IcpMode::kPointToPlane;
  const int stride = std::max(1, settings_.pixel_stride);
  const auto max_depth_m = static_cast<float>(settings_.max_depth_m);
  const auto inverse_voxel = static_cast<float>(1.0 / settings_.voxel_m);
  const int width = camera_.width();
  const int height = camera_.height();
  const auto point_at = [&](int u, int v, Eigen::Vector3f& point) {
    const unsigned short raw = depth.at<unsigned short>(v, u);
    if (raw == 0) return false;
    const float z_m = camera_.metres(raw);
    if (z_m > max_depth_m) return false;
    point = camera_.back_project(u, v, z_m);
    return true;
  };
  for (int v = 0; v < height; v += stride) {
    for (int u = 0; u < width; u += stride) {
      Eigen::Vector3f point;
      if (!point_at(u, v, point)) continue;
      Eigen::Vector3f normal = Eigen::Vector3f::Zero();
      if (want_normals && u >= kNormalSpan && v >= kNormalSpan && u + kNormalSpan < width && v + kNormalSpan < height) {
        // Central differences over the depth image; neighbours across a depth edge (more than
        // 5 % of the depth apart) would tilt the normal, so such pixels give none.
        Eigen::Vector3f left;
        Eigen::Vector3f right;
        Eigen::Vector3f up;
        Eigen::Vector3f down;
        if (point_at(u - kNormalSpan, v, left) && point_at(u + kNormalSpan, v, right) &&
            point_at(u, v - kNormalSpan, up) && point_at(u, v + kNormalSpan, down)) {
          const float limit = 0.05F * point.z();
          if (std::abs(left.z() - point.z()) < limit && std::abs(right.z() - point.z()) < limit &&
              std::abs(up.z() - point.z()) < limit && std::abs(down.z() - point.z()) < limit) {
            normal = (right - left).cross(down - up);
            const float length = normal.norm();
            if (length > 0.0F) {
              normal /= length;
              if (normal.dot(point) > 0.0F) normal = -normal;
            }
          }
        }
      }
      const int x = static_cast<int>(std::floor(point.x() * inverse_voxel));
      const int y = static_cast<int>(std::floor(point.y() * inverse_voxel));
      const int z = static_cast<int>(std::floor(point.z() * inverse_voxel));
      const std::int64_t key = voxel_key(x, y, z);
      std::size_t slot = hash_key(key) & impl.mask;
      while (impl.table[slot].key != kEmptyKey && impl.table[slot].key != key) slot = (slot + 1) & impl.mask;
      Impl::Voxel& voxel = impl.table[slot];
      if (voxel.key == kEmptyKey) {
        voxel.key = key;
        impl.used.push_back(slot);
      }
      voxel.sum += point;
      voxel.normal_sum += normal;
      ++voxel.count;
    }
  }
  for (const std::size_t slot : impl.used) {
    const Impl::Voxel& voxel = impl.table[slot];
    if (want_normals) {
      const float length = voxel.normal_sum.norm();
      if (length < 1e-3F) continue;  // no reliable normal: useless for point-to-plane
      cloud.normals.push_back(voxel.normal_sum / length);
    }
    cloud.points.push_back(voxel.sum / static_cast<float>(voxel.count));
  }
}

void IcpRefiner::set_target(const VoxelCloud& target, std::int64_t key) {
  Impl& impl = *impl_;
  if (impl.target == &target && impl.target_key == key) return;
  impl.target = &target;
  impl.target_key = key;
  impl.adaptor.points = &target.points;
  if (!target.points.empty()) impl.tree.buildIndex();
}

IcpResult IcpRefiner::align(const VoxelCloud& source, const Eigen::Isometry3d& T_target_source_initial) {
  Impl& impl = *impl_;
  IcpResult result;
  result.T_target_source = T_target_source_initial;
  if (impl.target == nullptr || impl.target->points.size() < 6 || source.points.size() < 6) {
    result.failure_reason = "cloud too small";
    return result;
  }
  const bool to_plane = settings_.mode == IcpMode::kPointToPlane;
  if (to_plane && impl.target->normals.size() != impl.target->points.size()) {
    result.failure_reason = "target has no normals";
    return result;
  }
  const std::size_t step =
      std::max<std::size_t>(1, source.points.size() / static_cast<std::size_t>(std::max(1, settings_.max_source_points)));
  const auto max_distance_sq = static_cast<float>(settings_.max_correspondence_m * settings_.max_correspondence_m);
  const std::size_t max_pairs = static_cast<std::size_t>(impl.pair_source.cols());
  Eigen::Isometry3d T = T_target_source_initial;
  nanoflann::KNNResultSet<float, std::uint32_t> nearest(1);
  for (int iteration = 0; iteration < settings_.max_iterations; ++iteration) {
    const Eigen::Isometry3f Tf = T.cast<float>();
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    std::size_t pairs = 0;
    double sum_sq = 0.0;
    for (std::size_t i = 0; i < source.points.size() && pairs < max_pairs; i += step) {
      const Eigen::Vector3f w = Tf * source.points[i];
      std::uint32_t index = 0;
      float distance_sq = 0.0F;
      nearest.init(&index, &distance_sq);
      impl.tree.findNeighbors(nearest, w.data(), nanoflann::SearchParams(10));
      if (distance_sq > max_distance_sq) continue;
      const Eigen::Vector3f& q = impl.target->points[index];
      if (to_plane) {
        const Eigen::Vector3d n = impl.target->normals[index].cast<double>();
        const Eigen::Vector3d wd = w.cast<double>();
        const double r = n.dot(wd - q.cast<double>());
        // Left perturbation T ← Exp(δ)·T: ∂r/∂δθ = w × n, ∂r/∂δt = n.
        Eigen::Matrix<double, 6, 1> J;
        J.head<3>() = wd.cross(n);
        J.tail<3>() = n;
        H.noalias() += J * J.transpose();
        b.noalias() += J * r;
        sum_sq += r * r;
      } else {
        impl.pair_source.col(static_cast<Eigen::Index>(pairs)) = source.points[i].cast<double>();
        impl.pair_target.col(static_cast<Eigen::Index>(pairs)) = q.cast<double>();
        sum_sq += static_cast<double>(distance_sq);
      }
      ++pairs;
    }
    result.iterations = iteration + 1;
    result.correspondences = static_cast<int>(pairs);
    result.rmse_m = pairs > 0 ? std::sqrt(sum_sq / static_cast<double>(pairs)) : 0.0;
    if (pairs < 6) {
      result.failure_reason = "too few correspondences";
      return result;
    }
    Eigen::Isometry3d next = T;
    if (to_plane) {
      const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> solver(H);
      if (solver.info() != Eigen::Success) {
        result.failure_reason = "degenerate geometry";
        return result;
      }
      const Eigen::Matrix<double, 6, 1> delta = -solver.solve(b);
      if (!delta.allFinite()) {
        result.failure_reason = "degenerate geometry";
        return result;
      }
      Eigen::Isometry3d update = Eigen::Isometry3d::Identity();
      update.linear() = exp_rotation(delta.head<3>());
      update.translation() = delta.tail<3>();
      next = update * T;
    } else {
      const auto count = static_cast<Eigen::Index>(pairs);
      if (robust::fit_rigid(impl.pair_source.leftCols(count), impl.pair_target.leftCols(count), {}, next) !=
          robust::RigidFitStatus::kOk) {
        result.failure_reason = "degenerate geometry";
        return result;
      }
    }
    const Eigen::Isometry3d change = next * T.inverse();
    T = next;
    if (Eigen::AngleAxisd(change.rotation()).angle() < settings_.min_update &&
        change.translation().norm() < settings_.min_update) {
      break;
    }
  }
  if (!T.matrix().allFinite()) {
    result.failure_reason = "non-finite estimate";
    return result;
  }
  result.ok = true;
  result.T_target_source = T;
  return result;
}

}  // namespace rankslam::slam
