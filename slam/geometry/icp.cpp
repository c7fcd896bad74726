#include "rankslam/geometry/icp.hpp"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "rankslam/robust/msse.hpp"
#include "rankslam/robust/scalar.hpp"

namespace rankslam::geometry {

namespace {

constexpr int kCellPx = 8;
// Fewer associations than this cannot constrain 6 parameters robustly.
constexpr int kMinAssociations = 12;

}  // namespace

std::string PlaneIcp::configure(const hal::CameraCalibration& calibration, int max_points,
                                parallel::ThreadTeam* team) {
  capacity_ = 0;
  team_ = team;
  if (max_points < kMinAssociations) return "geometry: ICP needs room for at least 12 points";
  if (calibration.width < 1 || calibration.height < 1 || !(calibration.fx > 0.0) ||
      !(calibration.fy > 0.0)) {
    return "geometry: ICP needs a calibrated camera (width, height, fx, fy)";
  }
  calibration_ = calibration;
  cells_x_ = (calibration.width + kCellPx - 1) / kCellPx;
  cells_y_ = (calibration.height + kCellPx - 1) / kCellPx;
  cell_start_.assign(static_cast<std::size_t>(cells_x_ * cells_y_ + 1), 0);
  const auto n = static_cast<std::size_t>(max_points);
  cell_points_.assign(n, 0);
  point_cell_.assign(n, -1);
  moved_.assign(n, Eigen::Vector3f::Zero());
  target_.assign(n, Eigen::Vector3f::Zero());
  target_normal_.assign(n, Eigen::Vector3f::Zero());
  squared_residuals_.assign(n, 0.0);
  inverse_sigma_.assign(n, 1.0F);
  associated_.assign(n, 0);
  workspace_.reserve(max_points);
  capacity_ = max_points;
  return {};
}

Eigen::Vector2f PlaneIcp::project(const Eigen::Vector3f& p) const {
  const double x = static_cast<double>(p.x()) / static_cast<double>(p.z());
  const double y = static_cast<double>(p.y()) / static_cast<double>(p.z());
  const auto& d = calibration_.distortion;
  double xd = x;
  double yd = y;
  if (calibration_.model == hal::CameraModel::kFisheye) {
    const double r = std::sqrt(x * x + y * y);
    if (r > 1e-12) {
      const double theta = std::atan(r);
      const double t2 = theta * theta;
      const double theta_d = theta * (1.0 + t2 * (d[0] + t2 * (d[1] + t2 * (d[2] + t2 * d[3]))));
      xd = x * theta_d / r;
      yd = y * theta_d / r;
    }
  } else {
    // OpenCV radial-tangential: k1 k2 p1 p2 k3.
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (d[0] + r2 * (d[1] + r2 * d[4]));
    xd = x * radial + 2.0 * d[2] * x * y + d[3] * (r2 + 2.0 * x * x);
    yd = y * radial + d[2] * (r2 + 2.0 * y * y) + 2.0 * d[3] * x * y;
  }
  return {static_cast<float>(calibration_.fx * xd + calibration_.cx),
          static_cast<float>(calibration_.fy * yd + calibration_.cy)};
}

void PlaneIcp::index_previous(const IcpCloud& previous) {
  // Counting sort of the previous points by the 8 × 8 pixel cell of their mean pixel.
  const int cells = cells_x_ * cells_y_;
  std::fill(cell_start_.begin(), cell_start_.begin() + cells + 1, 0);
  const int n = static_cast<int>(previous.points.size());
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2f& px = previous.pixels[static_cast<std::size_t>(i)];
    if ((max_curvature_ > 0.0F && !previous.curvature.empty() &&
         previous.curvature[static_cast<std::size_t>(i)] > max_curvature_) ||
        (max_depth_ > 0.0F && previous.points[static_cast<std::size_t>(i)].z() > max_depth_)) {
      point_cell_[static_cast<std::size_t>(i)] = -1;
      continue;
    }
    const int cx = static_cast<int>(px.x()) / kCellPx;
    const int cy = static_cast<int>(px.y()) / kCellPx;
    int cell = -1;
    if (px.x() >= 0.0F && px.y() >= 0.0F && cx < cells_x_ && cy < cells_y_) {
      cell = cy * cells_x_ + cx;
      ++cell_start_[static_cast<std::size_t>(cell + 1)];
    }
    point_cell_[static_cast<std::size_t>(i)] = cell;
  }
  for (int c = 0; c < cells; ++c) {
    cell_start_[static_cast<std::size_t>(c + 1)] += cell_start_[static_cast<std::size_t>(c)];
  }
  // Fill, using the starts as cursors, then shift them back.
  for (int i = 0; i < n; ++i) {
    const int cell = point_cell_[static_cast<std::size_t>(i)];
    if (cell < 0) continue;
    cell_points_[static_cast<std::size_t>(cell_start_[static_cast<std::size_t>(cell)]++)] = i;
  }
  for (int c = cells; c > 0; --c) {
    cell_start_[static_cast<std::size_t>(c)] = cell_start_[static_cast<std::size_t>(c - 1)];
  }
  cell_start_[0] = 0;
}

int PlaneIcp::associate(const IcpCloud& previous, const IcpCloud& current,
                        const Eigen::Isometry3d& T, int stride, float max_distance_m,
                        const IcpConfig& config) {
  const Eigen::Matrix3f R = T.rotation().cast<float>();
  const Eigen::Vector3f t = T.translation().cast<float>();
  const float max_d2 = max_distance_m * max_distance_m;
  const int n = static_cast<int>(current.points.size());
  // Sample s (current point s·stride) is associated into slot s on whichever thread, then the
  // associated samples are packed in order.
  const int samples = (n + stride - 1) / stride;
  const auto associate_samples = [&](int first, int end, int /*thread*/) {
    for (int s = first; s < end; ++s) {
      const auto c = static_cast<std::size_t>(s);
      associated_[c] = 0;
      const int i = s * stride;
      if (max_curvature_ > 0.0F && !current.curvature.empty() &&
          current.curvature[static_cast<std::size_t>(i)] > max_curvature_) {
        continue;
      }
      if (max_depth_ > 0.0F && current.points[static_cast<std::size_t>(i)].z() > max_depth_) continue;
      const Eigen::Vector3f p = R * current.points[static_cast<std::size_t>(i)] + t;
      if (!(p.z() > 0.0F)) continue;
      const Eigen::Vector2f px = project(p);
      if (!(px.x() > -kCellPx) || !(px.y() > -kCellPx)) continue;
      const int cx = static_cast<int>(std::floor(px.x() / static_cast<float>(kCellPx)));
      const int cy = static_cast<int>(std::floor(px.y() / static_cast<float>(kCellPx)));
      if (cx > cells_x_ || cy > cells_y_) continue;
      int best = -1;
      float best_d2 = max_d2;
      for (int y = std::max(cy - 1, 0); y <= std::min(cy + 1, cells_y_ - 1); ++y) {
        for (int x = std::max(cx - 1, 0); x <= std::min(cx + 1, cells_x_ - 1); ++x) {
          const int cell = y * cells_x_ + x;
          for (int k = cell_start_[static_cast<std::size_t>(cell)];
               k < cell_start_[static_cast<std::size_t>(cell + 1)]; ++k) {
            const int j = cell_points_[static_cast<std::size_t>(k)];
            const float d2 = (previous.points[static_cast<std::size_t>(j)] - p).squaredNorm();
            if (d2 <= best_d2) {
              best_d2 = d2;
              best = j;
            }
          }
        }
      }
      if (best < 0) continue;
      associated_[c] = 1;
      moved_[c] = p;
      target_[c] = previous.points[static_cast<std::size_t>(best)];
      target_normal_[c] = previous.normals[static_cast<std::size_t>(best)];
      float inverse_sigma = 1.0F;
      if (config.depth_noise_per_m > 0.0F) {
        const float z = target_[c].z();
        inverse_sigma = 1.0F / (config.depth_noise_per_m * z * z + config.noise_floor_m);
      }
      inverse_sigma_[c] = inverse_sigma;
      const auto r = static_cast<double>(target_normal_[c].dot(p - target_[c]) * inverse_sigma);
      squared_residuals_[c] = r * r;
    }
  };
  constexpr int kSamplesPerChunk = 128;
  parallel::for_chunks(team_, samples, kSamplesPerChunk, associate_samples);
  int count = 0;
  for (int s = 0; s < samples; ++s) {
    const auto from = static_cast<std::size_t>(s);
    if (associated_[from] == 0) continue;
    const auto to = static_cast<std::size_t>(count++);
    if (to == from) continue;
    moved_[to] = moved_[from];
    target_[to] = target_[from];
    target_normal_[to] = target_normal_[from];
    inverse_sigma_[to] = inverse_sigma_[from];
    squared_residuals_[to] = squared_residuals_[from];
  }
  return count;
}

int PlaneIcp::count_within(const IcpCloud& previous, const IcpCloud& current,
                           const Eigen::Isometry3d& T, const IcpConfig& config,
                           float max_residual_m) {
  if (!configured() || static_cast<int>(previous.points.size()) > capacity_ ||
      static_cast<int>(current.points.size()) > capacity_) {
    return 0;
  }
  max_curvature_ = config.max_curvature;
  max_depth_ = config.max_depth_m;
  index_previous(previous);
  const int n = static_cast<int>(current.points.size());
  const int stride = std::max(1, (n + config.max_points - 1) / std::max(config.max_points, 1));
  IcpConfig plain = config;
  plain.depth_noise_per_m = 0.0F;  // residuals in metres here
  const int count = associate(previous, current, T, stride, config.max_distance_m, plain);
  const double limit = static_cast<double>(max_residual_m) * static_cast<double>(max_residual_m);
  int within = 0;
  for (int k = 0; k < count; ++k) within += squared_residuals_[static_cast<std::size_t>(k)] <= limit ? 1 : 0;
  return within;
}

Eigen::Matrix<double, 6, 6> prior_where_data_are_weak(const Eigen::Matrix<double, 6, 6>& data_information,
                                                      const Eigen::Matrix<double, 6, 6>& prior_information,
                                                      double crossover) {
  if (!(crossover > 0.0)) return prior_information;
  // H v = λ P v with Vᵀ P V = I: in the coordinates y = V⁻¹ ε the prior is I and the data diag(λ).
  // The prior kept is P V diag(τ / (τ + λ)) Vᵀ P (V⁻ᵀ = P V).
  const Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> split(data_information,
                                                                                     prior_information);
  if (split.info() != Eigen::Success) return prior_information;
  const Eigen::Matrix<double, 6, 6> PV = prior_information * split.eigenvectors();
  Eigen::Matrix<double, 6, 1> kept;
  for (int k = 0; k < 6; ++k) kept(k) = crossover / (crossover + std::max(split.eigenvalues()(k), 0.0));
  const Eigen::Matrix<double, 6, 6> information = PV * kept.asDiagonal() * PV.transpose();
  return 0.5 * (information + information.transpose());
}

IcpResult PlaneIcp::refine(const IcpCloud& previous, const IcpCloud& current,
                           const Eigen::Isometry3d& initial, const IcpConfig& config) {
  IcpResult result;
  result.T_previous_current = initial;
  if (!configured() || static_cast<int>(previous.points.size()) > capacity_ ||
      static_cast<int>(current.points.size()) > capacity_ ||
      previous.normals.size() != previous.points.size() ||
      previous.pixels.size() != previous.points.size()) {
    return result;
  }
  max_curvature_ = config.max_curvature;
  max_depth_ = config.max_depth_m;
  index_previous(previous);
  const int n = static_cast<int>(current.points.size());
  const int stride = std::max(1, (n + config.max_points - 1) / std::max(config.max_points, 1));
  robust::ScalarModel model(robust::ScalarKind::kSquaredResidual);
  robust::MsseConfig msse;
  msse.min_inlier_fraction = config.min_inlier_fraction;
  msse.refit = false;
  Eigen::Isometry3d T = initial;
  for (int iteration = 0; iteration < config.max_iterations; ++iteration) {
    const int count = associate(previous, current, T, stride, config.max_distance_m, config);
    result.associations = count;
    if (count < kMinAssociations) return result;
    if (model.set_values(std::span<const double>(squared_residuals_.data(),
                                                 static_cast<std::size_t>(count))) !=
        robust::RobustStatus::kOk) {
      return result;
    }
    const auto segmentation = robust::estimate_msse(model, msse, workspace_);
    if (!segmentation.ok() || segmentation.inlier_count < kMinAssociations) return result;
    // Gauss-Newton on Σ (n·(p + ω×p + τ − q))² over the inliers.
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    double sum_sq = 0.0;
    for (const int k : segmentation.inliers) {
      const auto c = static_cast<std::size_t>(k);
      const Eigen::Vector3d p = moved_[c].cast<double>();
      const Eigen::Vector3d normal = target_normal_[c].cast<double>();
      const double r = normal.dot(p - target_[c].cast<double>());
      const auto w = static_cast<double>(inverse_sigma_[c]);  // residual and Jacobian in σ units
      Eigen::Matrix<double, 6, 1> a;
      a << p.cross(normal), normal;
      a *= w;
      H.selfadjointView<Eigen::Lower>().rankUpdate(a);
      g += a * (w * r);
      sum_sq += r * r;
    }
    H = H.selfadjointView<Eigen::Lower>();
    result.information = H;
    if (config.prior.information.any()) {
      // ε = log(T·prior⁻¹) moves to ε + δ under the update exp(δ)·T, to first order.
      const Eigen::Isometry3d off_prior = T * config.prior.T_previous_current.inverse();
      const Eigen::AngleAxisd rotation(off_prior.rotation());
      Eigen::Matrix<double, 6, 1> epsilon;
      epsilon << rotation.angle() * rotation.axis(), off_prior.translation();
      const Eigen::Matrix<double, 6, 6> information = prior_where_data_are_weak(H, config.prior.information,
                                                                               config.prior_crossover);
      H += information;
      g += information * epsilon;
    }
    result.inliers = segmentation.inlier_count;
    result.rms_m = std::sqrt(sum_sq / segmentation.inlier_count);
    result.iterations = iteration + 1;
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(H);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-12)) return result;
    const Eigen::Matrix<double, 6, 1> delta = -ldlt.solve(g);
    if (!delta.allFinite()) return result;
    const Eigen::Vector3d omega = delta.head<3>();
    Eigen::Isometry3d update = Eigen::Isometry3d::Identity();
    const double angle = omega.norm();
    if (angle > 0.0) update.linear() = Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
    update.translation() = delta.tail<3>();
    T = update * T;
    result.T_previous_current = T;
    result.ok = true;
    if (angle < config.min_update && delta.tail<3>().norm() < config.min_update) break;
  }
  return result;
}

}  // namespace rankslam::geometry
