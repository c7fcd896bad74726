#include "renderer.hpp"

#include <algorithm>
#include <cmath>

// The rays of a simulated camera's pixels (an ideal pinhole, or a fisheye through camera::Lens),
// with the bounding cones of pixel blocks the renderer culls scene quads against.
namespace rankslam::sim::detail {

std::optional<Eigen::Vector3d> CameraRays::unproject(double u, double v) const {
  if (pinhole) return Eigen::Vector3d((u - camera_.cx) / camera_.fx, (v - camera_.cy) / camera_.fy, 1.0);
  return lens_.unproject(u, v);
}

CameraRays::CameraRays(const hal::CameraCalibration& camera, double max_field_angle_rad)
    : camera_(camera), lens_(camera, max_field_angle_rad) {
  width = camera.width;
  height = camera.height;
  pinhole = camera.model == hal::CameraModel::kPinhole;
  const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  dx.assign(n, 0.0f);
  dy.assign(n, 0.0f);
  dz.assign(n, 0.0f);
  inv_norm.assign(n, 0.0f);
  valid.assign(n, 0);
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u);
      const auto d = unproject(u, v);
      if (!d) continue;
      dx[i] = static_cast<float>(d->x());
      dy[i] = static_cast<float>(d->y());
      dz[i] = static_cast<float>(d->z());
      inv_norm[i] = static_cast<float>(1.0 / d->norm());
      valid[i] = 1;
    }
  }
  tiles_x = (width + kTile - 1) / kTile;
  tiles_y = (height + kTile - 1) / kTile;
  const std::size_t tile_count = static_cast<std::size_t>(tiles_x) * static_cast<std::size_t>(tiles_y);
  tiles.assign(tile_count, Cone{});
  tile_dx.assign(tile_count * kTilePixels, 0.0f);
  tile_dy.assign(tile_count * kTilePixels, 0.0f);
  tile_dz.assign(tile_count * kTilePixels, 0.0f);
  frame_half_angle_rad = 0.0;
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const std::size_t tile = static_cast<std::size_t>(ty * tiles_x + tx);
      std::vector<Eigen::Vector3d> rays;
      for (int v = ty * kTile; v < std::min(height, (ty + 1) * kTile); ++v) {
        for (int u = tx * kTile; u < std::min(width, (tx + 1) * kTile); ++u) {
          const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(width) + static_cast<std::size_t>(u);
          if (!valid[i]) continue;
          const std::size_t j = tile * kTilePixels + static_cast<std::size_t>((v - ty * kTile) * kTile + (u - tx * kTile));
          tile_dx[j] = dx[i];
          tile_dy[j] = dy[i];
          tile_dz[j] = dz[i];
          rays.push_back(Eigen::Vector3d(dx[i], dy[i], dz[i]).normalized());
        }
      }
      Cone& cone = tiles[tile];
      if (rays.empty()) continue;
      Eigen::Vector3d sum = Eigen::Vector3d::Zero();
      for (const auto& d : rays) sum += d;
      const Eigen::Vector3d axis = sum.normalized();
      double half = 0.0;
      for (const auto& d : rays) half = std::max(half, std::acos(std::clamp(axis.dot(d), -1.0, 1.0)));
      half += 1e-3;
      cone.ax = static_cast<float>(axis.x());
      cone.ay = static_cast<float>(axis.y());
      cone.az = static_cast<float>(axis.z());
      cone.cos_half = static_cast<float>(std::cos(half));
      cone.sin_half = static_cast<float>(std::sin(half));
      cone.any_valid = true;
      frame_half_angle_rad = std::max(frame_half_angle_rad, std::acos(std::clamp(axis.z(), -1.0, 1.0)) + half);
      // Side planes through the rays of the tile's (slightly enlarged) corners; kept only
      // when every ray of the tile is verified to lie inside.
      for (const double margin : {0.5, 1.0, 2.0, 4.0}) {
        const double u0 = tx * kTile - margin;
        const double u1 = std::min(width, (tx + 1) * kTile) - 1 + margin;
        const double v0 = ty * kTile - margin;
        const double v1 = std::min(height, (ty + 1) * kTile) - 1 + margin;
        const auto c00 = unproject(u0, v0);
        const auto c10 = unproject(u1, v0);
        const auto c11 = unproject(u1, v1);
        const auto c01 = unproject(u0, v1);
        if (!c00 || !c10 || !c11 || !c01) break;
        const std::array<Eigen::Vector3d, 4> corners = {c00->normalized(), c10->normalized(), c11->normalized(),
                                                        c01->normalized()};
        bool inside = true;
        std::array<Eigen::Vector3d, 4> normals;
        for (std::size_t e = 0; e < 4; ++e) {
          normals[e] = corners[e].cross(corners[(e + 1) % 4]).normalized();
          if (normals[e].dot(axis) < 0.0) normals[e] = -normals[e];
          for (const auto& d : rays) inside = inside && normals[e].dot(d) >= 1e-7;
        }
        if (!inside) continue;
        for (std::size_t e = 0; e < 4; ++e) {
          for (int c = 0; c < 3; ++c) cone.planes[e][static_cast<std::size_t>(c)] = static_cast<float>(normals[e][c]);
        }
        cone.has_planes = true;
        break;
      }
    }
  }
  pixel_angle_rad = static_cast<float>(1.0 / camera.fx);
}

}  // namespace rankslam::sim::detail
