#include "rankslam/sim/scene.hpp"
#include "rankslam/core/units.hpp"

#include "texture.hpp"

#include "rankslam/sim/simulator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace rankslam::sim {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
constexpr double kPi = std::numbers::pi;
// Large surfaces are split so per-tile culling by bounding spheres stays effective.
constexpr double kMaxPiece_m = 1.0;

HarmonicSignal harmonic(double offset, std::initializer_list<HarmonicSignal::Term> terms) {
  HarmonicSignal signal;
  signal.offset = offset;
  signal.terms = terms;
  return signal;
}

// Assembles surfaces; every helper keeps the one-sided convention (normal = axis_u × axis_v
// points into free space).
class SceneBuilder {
 public:
  explicit SceneBuilder(SceneModel& scene) : scene_(scene) {}

  int material(Material m) {
    scene_.materials.push_back(std::move(m));
    return static_cast<int>(scene_.materials.size()) - 1;
  }
  int texture(Texture t) {
    scene_.textures.push_back(std::move(t));
    return static_cast<int>(scene_.textures.size()) - 1;
  }

  // Rectangle with centre, outward normal and "up" direction (⟂ normal); split into pieces.
  void rect(const Vector3d& center, const Vector3d& normal, const Vector3d& up, double half_w, double half_h,
            int material, const Vector2d& texture_origin) {
    const Vector3d v = up.normalized();
    const Vector3d u = v.cross(normal.normalized()).normalized();
    const int nu = std::max(1, static_cast<int>(std::ceil(2.0 * half_w / kMaxPiece_m - 1e-9)));
    const int nv = std::max(1, static_cast<int>(std::ceil(2.0 * half_h / kMaxPiece_m - 1e-9)));
    const double pu = 2.0 * half_w / nu;
    const double pv = 2.0 * half_h / nv;
    for (int j = 0; j < nv; ++j) {
      for (int i = 0; i < nu; ++i) {
        SurfaceQuad q;
        q.axis_u = u;
        q.axis_v = v;
        q.half_u_m = pu / 2.0;
        q.half_v_m = pv / 2.0;
        q.center_m = center + (-half_w + (i + 0.5) * pu) * u + (half_h - (j + 0.5) * pv) * v;
        q.material = material;
        q.texture_origin_m = texture_origin + Vector2d(i * pu, j * pv);
        scene_.surfaces.push_back(q);
      }
    }
  }

  // Vertical wall over the floor segment a → b, facing to the right of a → b.
  void wall(const Vector2d& a, const Vector2d& b, double z0, double z1, int material, double texture_x0 = 0.0) {
    const Vector2d e = (b - a).normalized();
    const Vector3d normal(e.y(), -e.x(), 0.0);
    const Vector2d mid = 0.5 * (a + b);
    rect(Vector3d(mid.x(), mid.y(), 0.5 * (z0 + z1)), normal, Vector3d::UnitZ(), 0.5 * (b - a).norm(), 0.5 * (z1 - z0),
         material, Vector2d(texture_x0, -z1));
  }

  struct Opening {
    double along_m = 0.0;  // centre, measured from a
    double width_m = 0.9;
    double height_m = 2.05;
    double depth_m = 0.12;
    int door_material = 0;
  };

  // Wall with door recesses: wall pieces around each opening, a lintel above it, and the
  // recess (two jambs, a head and the door leaf at the back).
  void wall_with_openings(const Vector2d& a, const Vector2d& b, double z0, double z1, int material,
                          std::vector<Opening> openings, int trim_material) {
    std::sort(openings.begin(), openings.end(), [](const Opening& x, const Opening& y) { return x.along_m < y.along_m; });
    const Vector2d e = (b - a).normalized();
    const double length = (b - a).norm();
    const Vector3d e3(e.x(), e.y(), 0.0);
    const Vector3d n(e.y(), -e.x(), 0.0);
    double cursor = 0.0;
    auto at = [&](double s) { return Vector2d(a + s * e); };
    for (const auto& o : openings) {
      const double left = o.along_m - o.width_m / 2;
      const double right = o.along_m + o.width_m / 2;
      if (left > cursor + 1e-6) wall(at(cursor), at(left), z0, z1, material, cursor);
      wall(at(left), at(right), z0 + o.height_m, z1, material, left);
      const Vector2d c2 = at(o.along_m);
      const Vector3d c(c2.x(), c2.y(), 0.0);
      const double zc = z0 + o.height_m / 2;
      // Door leaf at the back of the recess, facing the corridor.
      rect(c - o.depth_m * n + Vector3d(0, 0, zc), n, Vector3d::UnitZ(), o.width_m / 2, o.height_m / 2,
           o.door_material, Vector2d(0.0, 0.0));
      // Jambs face the opening's centre.
      rect(c - (o.width_m / 2) * e3 - (o.depth_m / 2) * n + Vector3d(0, 0, zc), e3, Vector3d::UnitZ(),
           o.depth_m / 2, o.height_m / 2, trim_material, Vector2d(0.0, 0.0));
      rect(c + (o.width_m / 2) * e3 - (o.depth_m / 2) * n + Vector3d(0, 0, zc), -e3, Vector3d::UnitZ(),
           o.depth_m / 2, o.height_m / 2, trim_material, Vector2d(0.0, 0.0));
      // Head of the recess faces down.
      rect(c - (o.depth_m / 2) * n + Vector3d(0, 0, z0 + o.height_m), -Vector3d::UnitZ(), e3, o.depth_m / 2,
           o.width_m / 2, trim_material, Vector2d(0.0, 0.0));
      cursor = right;
    }
    if (length > cursor + 1e-6) wall(at(cursor), b, z0, z1, material, cursor);
  }

  // Axis-aligned (up to yaw) box. `faces` bit mask: +x −x +y −y +z −z (bit 0..5).
  void box(const Vector3d& center, const Vector3d& half, double yaw_rad, int material,
           const Vector2d& texture_origin = Vector2d::Zero(), unsigned faces = 0x1FU) {
    const Vector3d ex(std::cos(yaw_rad), std::sin(yaw_rad), 0.0);
    const Vector3d ey(-std::sin(yaw_rad), std::cos(yaw_rad), 0.0);
    const Vector3d ez = Vector3d::UnitZ();
    // Each face gets its own patch of the texture so neighbouring faces differ.
    const Vector2d step(0.37, 0.23);
    if (faces & 0x01U) rect(center + half.x() * ex, ex, ez, half.y(), half.z(), material, texture_origin);
    if (faces & 0x02U) rect(center - half.x() * ex, -ex, ez, half.y(), half.z(), material, texture_origin + step);
    if (faces & 0x04U) rect(center + half.y() * ey, ey, ez, half.x(), half.z(), material, texture_origin + 2 * step);
    if (faces & 0x08U) rect(center - half.y() * ey, -ey, ez, half.x(), half.z(), material, texture_origin + 3 * step);
    if (faces & 0x10U) rect(center + half.z() * ez, ez, ey, half.x(), half.y(), material, texture_origin + 4 * step);
    if (faces & 0x20U) rect(center - half.z() * ez, -ez, ey, half.x(), half.y(), material, texture_origin + 5 * step);
  }

  // Horizontal rectangle [x0, x1] × [y0, y1] at height z, facing up or down.
  void horizontal(double x0, double x1, double y0, double y1, double z, bool facing_up, int material) {
    const Vector3d center(0.5 * (x0 + x1), 0.5 * (y0 + y1), z);
    if (facing_up) {
      rect(center, Vector3d::UnitZ(), Vector3d::UnitY(), 0.5 * (x1 - x0), 0.5 * (y1 - y0), material, Vector2d(x0, -y1));
    } else {
      rect(center, -Vector3d::UnitZ(), Vector3d::UnitY(), 0.5 * (x1 - x0), 0.5 * (y1 - y0), material, Vector2d(-x1, -y1));
    }
  }

  // Table: top slab and four legs.
  void table(const Vector3d& top_center, const Vector2d& half_xy, double height, int top_material, int leg_material) {
    box(top_center, Vector3d(half_xy.x(), half_xy.y(), 0.02), 0.0, top_material, Vector2d::Zero(), 0x3FU);
    const double leg_half = (height - 0.04) / 2;
    for (const double sx : {-1.0, 1.0}) {
      for (const double sy : {-1.0, 1.0}) {
        box(Vector3d(top_center.x() + sx * (half_xy.x() - 0.05), top_center.y() + sy * (half_xy.y() - 0.05), leg_half),
            Vector3d(0.025, 0.025, leg_half), 0.0, leg_material, Vector2d::Zero(), 0x0FU);
      }
    }
  }

 private:
  SceneModel& scene_;
};

Material uniform(const std::string& name, float b, float g, float r, float ir = 0.6f) {
  Material m;
  m.name = name;
  m.albedo_bgr = Eigen::Vector3f(b, g, r);
  m.ir_reflectance = ir;
  return m;
}

Material textured(const std::string& name, int texture, float ir = 0.6f, float ir_contrast = 0.8f) {
  Material m;
  m.name = name;
  m.albedo_bgr = Eigen::Vector3f::Ones();
  m.texture = texture;
  m.ir_reflectance = ir;
  m.ir_texture_contrast = ir_contrast;
  return m;
}

Material lamp(const std::string& name, float emission) {
  Material m = uniform(name, 0.9f, 0.9f, 0.9f, 0.5f);
  m.emission = emission;
  return m;
}

hal::CameraCalibration kinect_rgb(const Eigen::Isometry3d& T_base_cam) {
  hal::CameraCalibration camera;
  camera.model = hal::CameraModel::kPinhole;
  camera.width = 640;
  camera.height = 480;
  camera.fx = 517.3;
  camera.fy = 516.5;
  camera.cx = 318.6;
  camera.cy = 255.3;
  camera.distortion = {0.0, 0.0, 0.0, 0.0, 0.0};
  camera.T_base_cam = T_base_cam;
  camera.T_base_cam_given = true;
  return camera;
}

Eigen::Isometry3d pose(const Eigen::Matrix3d& R, const Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

// ---------------------------------------------------------------------------------------------
// office / dark-office

void build_office(SceneModel& scene, std::uint64_t seed, bool dark) {
  SceneBuilder b(scene);
  const int wall_paint = b.texture(detail::paint_texture(seed + 1, 512, 0.008, {0.78f, 0.82f, 0.84f}, 0.05f));
  const int carpet = b.texture(detail::carpet_texture(seed + 2, 1024, 0.003, {0.42f, 0.36f, 0.30f}));
  const int wood = b.texture(detail::wood_texture(seed + 3, 1024, 0.0015, {0.28f, 0.45f, 0.62f}));
  const int dark_wood = b.texture(detail::wood_texture(seed + 4, 1024, 0.002, {0.16f, 0.24f, 0.36f}));
  const int posters = b.texture(detail::poster_atlas_texture(seed + 5, 2048, 4, 0.0016));
  const int cardboard = b.texture(detail::cardboard_texture(seed + 6, 1024, 0.001));
  const int whiteboard = b.texture(detail::whiteboard_texture(seed + 7, 1024, 0.0016));

  const int m_wall = b.material(textured("wall paint", wall_paint, 0.7f, 0.5f));
  const int m_ceiling = b.material(uniform("ceiling", 0.86f, 0.88f, 0.88f, 0.7f));
  const int m_floor = b.material(textured("carpet", carpet, 0.45f, 0.9f));
  const int m_wood = b.material(textured("desk wood", wood, 0.55f, 0.6f));
  const int m_dark_wood = b.material(textured("door wood", dark_wood, 0.45f, 0.6f));
  const int m_metal = b.material(uniform("metal", 0.35f, 0.36f, 0.38f, 0.5f));
  const int m_black = b.material(uniform("plastic", 0.07f, 0.07f, 0.08f, 0.25f));
  const int m_posters = b.material(textured("posters", posters, 0.6f, 1.0f));
  const int m_cardboard = b.material(textured("cardboard", cardboard, 0.65f, 0.8f));
  const int m_whiteboard = b.material(textured("whiteboard", whiteboard, 0.8f, 0.9f));
  const int m_lamp = b.material(lamp("lamp", dark ? 0.0f : 3.0f));
  const double cell = 2048 * 0.0016 / 4;  // poster atlas cell, metres

  const double H = 2.6;
  b.wall({2.5, -2.0}, {-2.5, -2.0}, 0.0, H, m_wall, 0.0);
  b.wall({-2.5, -2.0}, {-2.5, 2.0}, 0.0, H, m_wall, 5.0);
  b.wall({-2.5, 2.0}, {2.5, 2.0}, 0.0, H, m_wall, 9.0);
  b.wall({2.5, 2.0}, {2.5, -2.0}, 0.0, H, m_wall, 14.0);
  b.horizontal(-2.5, 2.5, -2.0, 2.0, 0.0, true, m_floor);
  b.horizontal(-2.5, 2.5, -2.0, 2.0, H, false, m_ceiling);
  for (const double x : {-1.2, 1.2}) {
    for (const double y : {-1.0, 1.0}) b.horizontal(x - 0.3, x + 0.3, y - 0.15, y + 0.15, H - 0.01, false, m_lamp);
  }

  // Desk A along the east wall with a monitor, keyboard and books; desk B along the north wall.
  b.table({2.1, -0.3, 0.73}, {0.38, 0.8}, 0.75, m_wood, m_metal);
  b.table({0.3, 1.62, 0.73}, {0.8, 0.36}, 0.75, m_wood, m_metal);
  b.box({2.33, -0.4, 1.02}, {0.025, 0.27, 0.17}, 0.0, m_black);
  b.rect({2.303, -0.4, 1.03}, -Vector3d::UnitX(), Vector3d::UnitZ(), 0.25, 0.145, m_posters, {2 * cell + 0.05, cell + 0.1});
  b.box({2.36, -0.4, 0.8}, {0.06, 0.09, 0.05}, 0.0, m_black);
  b.box({1.95, -0.42, 0.762}, {0.07, 0.22, 0.012}, 0.0, m_black);
  b.box({2.02, 0.28, 0.775}, {0.13, 0.1, 0.025}, 0.1, m_posters, {0.05, 0.05});
  b.box({2.04, 0.26, 0.825}, {0.12, 0.09, 0.025}, -0.25, m_posters, {cell + 0.05, 2 * cell + 0.05});
  b.box({2.0, 0.3, 0.87}, {0.11, 0.085, 0.02}, 0.4, m_posters, {3 * cell + 0.05, 0.05});
  b.box({1.75, 0.1, 0.8}, {0.04, 0.04, 0.05}, 0.0, m_posters, {3 * cell + 0.2, 3 * cell + 0.3});
  // Chair and bin.
  b.box({1.5, 0.75, 0.46}, {0.22, 0.22, 0.03}, 0.15, m_black);
  b.box({1.72, 0.78, 0.76}, {0.02, 0.22, 0.26}, 0.15, m_black);
  b.box({1.5, 0.75, 0.215}, {0.025, 0.025, 0.215}, 0.0, m_metal, Vector2d::Zero(), 0x0FU);
  b.box({2.2, 0.8, 0.18}, {0.12, 0.12, 0.18}, 0.0, m_metal);
  // Desk B: cardboard box, a laptop-sized slab and a shelf of books above.
  b.box({0.8, 1.7, 0.87}, {0.18, 0.14, 0.12}, 0.3, m_cardboard, {0.1, 0.1});
  b.box({0.1, 1.55, 0.76}, {0.17, 0.12, 0.01}, -0.2, m_metal);
  b.box({0.9, 1.88, 1.35}, {0.4, 0.12, 0.015}, 0.0, m_wood);
  for (int i = 0; i < 7; ++i) {
    const double x = 0.6 + 0.075 * i;
    const double h = 0.1 + 0.02 * (i % 3);
    b.box({x, 1.9, 1.365 + h}, {0.03, 0.09, h}, 0.0, m_posters, {(i % 4) * cell + 0.1, (i / 4 + 1) * cell + 0.2});
  }
  // Cardboard boxes on the floor, a cabinet by the south wall.
  b.box({1.6, -1.6, 0.2}, {0.3, 0.22, 0.2}, 0.1, m_cardboard, {0.0, 0.0});
  b.box({1.55, -1.55, 0.52}, {0.2, 0.16, 0.12}, -0.2, m_cardboard, {0.3, 0.4});
  b.box({-2.0, 1.4, 0.25}, {0.3, 0.3, 0.25}, 0.05, m_cardboard, {0.5, 0.2});
  b.box({-0.6, -1.78, 0.55}, {0.45, 0.2, 0.55}, 0.0, m_wood);
  b.box({-0.8, -1.8, 1.2}, {0.12, 0.1, 0.1}, 0.2, m_cardboard, {0.6, 0.6});
  // Whiteboard, posters and a door on the walls.
  b.rect({0.3, 1.995, 1.55}, -Vector3d::UnitY(), Vector3d::UnitZ(), 0.8, 0.45, m_whiteboard, {0.0, 0.0});
  b.rect({2.495, 0.55, 1.6}, -Vector3d::UnitX(), Vector3d::UnitZ(), 0.3, 0.4, m_posters, {0.0, 0.0});
  b.rect({2.495, -1.4, 1.5}, -Vector3d::UnitX(), Vector3d::UnitZ(), 0.35, 0.4, m_posters, {cell, 0.0});
  b.rect({1.0, -1.995, 1.6}, Vector3d::UnitY(), Vector3d::UnitZ(), 0.4, 0.3, m_posters, {2 * cell, 0.0});
  b.rect({-2.495, 0.0, 1.5}, Vector3d::UnitX(), Vector3d::UnitZ(), 0.38, 0.4, m_posters, {3 * cell, cell});
  b.rect({-1.5, 1.995, 1.5}, -Vector3d::UnitY(), Vector3d::UnitZ(), 0.35, 0.4, m_posters, {0.0, 2 * cell});
  b.rect({-2.495, -1.2, 1.02}, Vector3d::UnitX(), Vector3d::UnitZ(), 0.45, 1.02, m_dark_wood, {0.0, 0.0});

  for (const double x : {-1.2, 1.2}) {
    for (const double y : {-1.0, 1.0}) scene.lights.push_back({Vector3d(x, y, H - 0.15), 1.6});
  }
  scene.lights.push_back({Vector3d(2.0, -1.2, 1.4), 0.5});  // desk lamp

  HandheldMotion motion;
  motion.period_s = 10.0;
  motion.position_m = {harmonic(-0.2, {{1, 0.55, 0.0}, {2, 0.14, 1.0}, {3, 0.05, 2.0}}),
                       harmonic(-0.3, {{1, 0.5, 1.3}, {3, 0.09, 0.5}}),
                       harmonic(1.35, {{2, 0.15, 0.4}, {3, 0.05, 1.3}})};
  motion.target_m = {harmonic(1.7, {{1, 0.45, 0.5}, {2, 0.2, 1.7}, {3, 0.1, 0.1}}),
                     harmonic(0.45, {{1, 1.3, -0.8}, {2, 0.5, 0.3}, {4, 0.1, 0.6}, {5, 0.05, 2.1}}),
                     harmonic(0.9, {{2, 0.22, 0.9}, {3, 0.16, 0.0}, {5, 0.07, 1.1}})};
  motion.roll_rad = harmonic(0.0, {{1, 0.2, 0.2}, {3, 0.12, 1.0}, {4, 0.04, 0.4}});
  scene.motion = motion;
  scene.default_frames = 300;

  if (dark) {
    // Lights off: a little daylight through a door gap, the colour camera at full gain.
    scene.photometry.ambient = 0.1;
    scene.photometry.exposure_key = 0.0008;
    scene.photometry.read_noise_levels = 3.2;
    scene.photometry.shot_noise_gain = 0.3;
    scene.lights.clear();
    scene.has_ir = true;
  } else {
    scene.photometry.exposure_key = 0.18;
  }
}

// ---------------------------------------------------------------------------------------------
// zigzag-plain

void build_zigzag(SceneModel& scene) {
  SceneBuilder b(scene);
  const int m_panel = b.material(uniform("panel", 0.74f, 0.75f, 0.76f, 0.75f));
  const int m_floor = b.material(uniform("floor", 0.42f, 0.44f, 0.45f, 0.5f));
  const int m_wall = b.material(uniform("wall", 0.62f, 0.64f, 0.66f, 0.65f));
  const double H = 2.6;
  b.wall({3.5, -3.0}, {-3.5, -3.0}, 0.0, H, m_wall);
  b.wall({-3.5, -3.0}, {-3.5, 2.5}, 0.0, H, m_wall);
  b.wall({-3.5, 2.5}, {3.5, 2.5}, 0.0, H, m_wall);
  b.wall({3.5, 2.5}, {3.5, -3.0}, 0.0, H, m_wall);
  b.horizontal(-3.5, 3.5, -3.0, 2.5, 0.0, true, m_floor);
  b.horizontal(-3.5, 3.5, -3.0, 2.5, H, false, m_wall);
  // Eight panels folded at ±40° to the x axis, standing on the floor, facing −y.
  const int panels = 8;
  const double width = 0.5;
  const double angle = deg_to_rad(40.0);
  const double step_x = width * std::cos(angle);
  Vector2d p(-0.5 * panels * step_x, 0.0);
  for (int i = 0; i < panels; ++i) {
    const Vector2d q(p.x() + step_x, (i % 2 == 0) ? width * std::sin(angle) : 0.0);
    // Walking p → q with the panel facing right of the walk direction means facing −y.
    b.wall(p, q, 0.0, 0.9, m_panel);
    p = q;
  }
  scene.lights.push_back({Vector3d(-1.2, -1.6, 2.3), 1.8});
  scene.lights.push_back({Vector3d(1.5, -0.4, 2.4), 1.4});
  scene.photometry.ambient = 0.2;
  scene.photometry.exposure_key = 0.2;

  HandheldMotion motion;
  motion.period_s = 10.0;
  motion.position_m = {harmonic(0.0, {{1, 1.0, 0.0}, {2, 0.1, 0.7}}), harmonic(-1.35, {{2, 0.1, 1.0}}),
                       harmonic(1.15, {{3, 0.06, 0.2}})};
  motion.target_m = {harmonic(0.0, {{1, 0.8, 0.0}, {3, 0.12, 0.5}}), harmonic(0.15, {{2, 0.1, 0.0}}),
                     harmonic(0.35, {{2, 0.08, 0.3}})};
  motion.roll_rad = harmonic(0.0, {{1, 0.06, 0.9}});
  scene.motion = motion;
  scene.default_frames = 300;
}

// ---------------------------------------------------------------------------------------------
// poster-wall

void build_poster_wall(SceneModel& scene, std::uint64_t seed) {
  SceneBuilder b(scene);
  const double texel = 0.003;
  const int wall_texture = b.texture(detail::poster_wall_texture(seed + 21, 2048, 2048, texel));
  const int m_wall = b.material(textured("poster wall", wall_texture, 0.6f, 1.0f));
  // One plane, 2048 × 1536 texels of the texture, nothing else in the scene.
  b.rect({0.0, 1.5, 1.5}, -Vector3d::UnitY(), Vector3d::UnitZ(), 1024 * texel, 768 * texel, m_wall, {0.0, 0.0});
  scene.lights.push_back({Vector3d(-1.2, -0.8, 2.6), 2.0});
  scene.lights.push_back({Vector3d(1.4, -1.2, 2.2), 2.0});
  scene.photometry.ambient = 0.2;
  scene.photometry.exposure_key = 0.2;

  HandheldMotion motion;
  motion.period_s = 10.0;
  motion.position_m = {harmonic(0.0, {{1, 0.9, 0.0}, {3, 0.1, 0.4}}), harmonic(0.1, {{2, 0.15, 1.1}}),
                       harmonic(1.5, {{1, 0.2, 1.0}, {2, 0.05, 0.1}})};
  motion.target_m = {harmonic(0.0, {{1, 0.7, 0.0}, {2, 0.25, 0.5}}), harmonic(1.5, {}),
                     harmonic(1.5, {{1, 0.25, 2.0}, {3, 0.06, 0.7}})};
  motion.roll_rad = harmonic(0.0, {{1, 0.12, 0.3}, {4, 0.04, 0.2}});
  scene.motion = motion;
  scene.default_frames = 300;
}

// ---------------------------------------------------------------------------------------------
// corridor-loop

void build_corridor(SceneModel& scene, std::uint64_t seed) {
  SceneBuilder b(scene);
  const int plaster = b.texture(detail::paint_texture(seed + 31, 512, 0.01, {0.74f, 0.80f, 0.82f}, 0.03f));
  const int floor_tex = b.texture(detail::paint_texture(seed + 32, 512, 0.006, {0.45f, 0.47f, 0.48f}, 0.06f));
  const int door_tex = b.texture(detail::wood_texture(seed + 33, 512, 0.003, {0.22f, 0.35f, 0.52f}));
  const int posters = b.texture(detail::poster_atlas_texture(seed + 34, 1024, 2, 0.0008));
  const int cardboard = b.texture(detail::cardboard_texture(seed + 35, 1024, 0.001));
  const int m_wall = b.material(textured("plaster", plaster, 0.7f, 0.4f));
  const int m_floor = b.material(textured("linoleum", floor_tex, 0.5f, 0.5f));
  const int m_ceiling = b.material(uniform("ceiling", 0.85f, 0.87f, 0.87f, 0.7f));
  const int m_door = b.material(textured("door", door_tex, 0.45f, 0.5f));
  const int m_trim = b.material(uniform("door frame", 0.55f, 0.57f, 0.58f, 0.6f));
  const int m_pillar = b.material(uniform("pillar", 0.66f, 0.70f, 0.72f, 0.65f));
  const int m_notice = b.material(textured("notice", posters, 0.6f, 1.0f));
  const int m_box = b.material(textured("cardboard", cardboard, 0.65f, 0.8f));
  const int m_bench = b.material(uniform("bench", 0.25f, 0.3f, 0.45f, 0.5f));
  const int m_lamp = b.material(lamp("lamp", 3.5f));

  // Centre line: rectangle (0,0)-(6,4); corridor 1.6 m wide; inner block in the middle.
  const double H = 2.5;
  const double w = 0.8;
  const double x0 = -w;
  const double x1 = 6.0 + w;
  const double y0 = -w;
  const double y1 = 4.0 + w;
  using Opening = SceneBuilder::Opening;
  // Outer walls, clockwise seen from above so they face inwards. The north wall between
  // x = 1.6 and 4.4 stays blank: the robot turns to face it.
  b.wall_with_openings({x1, y0}, {x0, y0}, 0.0, H, m_wall,
                       {Opening{x1 - 1.8, 0.9, 2.05, 0.12, m_door}, Opening{x1 - 4.6, 0.9, 2.05, 0.12, m_door}}, m_trim);
  b.wall({x0, y0}, {x0, y1}, 0.0, H, m_wall, 7.6);
  b.wall_with_openings({x0, y1}, {x1, y1}, 0.0, H, m_wall, {Opening{5.4 - x0, 0.9, 2.05, 0.12, m_door}}, m_trim);
  b.wall_with_openings({x1, y1}, {x1, y0}, 0.0, H, m_wall, {Opening{y1 - 2.0, 0.9, 2.05, 0.12, m_door}}, m_trim);
  // Inner block, counter-clockwise so its walls face outwards.
  b.wall({w, w}, {6.0 - w, w}, 0.0, H, m_wall, 0.0);
  b.wall({6.0 - w, w}, {6.0 - w, 4.0 - w}, 0.0, H, m_wall, 4.4);
  b.wall({6.0 - w, 4.0 - w}, {w, 4.0 - w}, 0.0, H, m_wall, 6.8);
  b.wall({w, 4.0 - w}, {w, w}, 0.0, H, m_wall, 11.2);
  // Floor and ceiling as four strips around the inner block.
  const std::array<std::array<double, 4>, 4> strips = {{{x0, x1, y0, w}, {x0, x1, 4.0 - w, y1}, {x0, w, w, 4.0 - w},
                                                        {6.0 - w, x1, w, 4.0 - w}}};
  for (const auto& s : strips) {
    b.horizontal(s[0], s[1], s[2], s[3], 0.0, true, m_floor);
    b.horizontal(s[0], s[1], s[2], s[3], H, false, m_ceiling);
  }
  // Pillars, boxes, a bench and two notices.
  b.box({x0 + 0.1, 2.0, H / 2}, {0.2, 0.18, H / 2}, 0.0, m_pillar, Vector2d::Zero(), 0x0FU);
  b.box({3.0, w - 0.05, H / 2}, {0.17, 0.2, H / 2}, 0.0, m_pillar, Vector2d::Zero(), 0x0FU);
  b.box({6.0 - w + 0.05, 2.0, H / 2}, {0.2, 0.17, H / 2}, 0.0, m_pillar, Vector2d::Zero(), 0x0FU);
  b.box({4.0, y0 + 0.25, 0.2}, {0.22, 0.2, 0.2}, 0.15, m_box, {0.1, 0.1});
  b.box({x1 - 0.3, 3.3, 0.25}, {0.2, 0.25, 0.25}, -0.1, m_box, {0.3, 0.2});
  b.box({x0 + 0.28, 3.1, 0.17}, {0.2, 0.16, 0.17}, 0.3, m_box, {0.5, 0.5});
  b.box({1.6, 4.0 - w + 0.2, 0.22}, {0.5, 0.18, 0.22}, 0.0, m_bench);
  b.rect({2.2, w - 0.004, 1.5}, -Vector3d::UnitY(), Vector3d::UnitZ(), 0.2, 0.28, m_notice, {0.0, 0.0});
  b.rect({x1 - 0.004, 0.9, 1.5}, -Vector3d::UnitX(), Vector3d::UnitZ(), 0.2, 0.28, m_notice, {0.41, 0.41});

  // Lamps every 2 m above the centre line.
  const std::array<Vector2d, 10> lamp_xy = {Vector2d(0, 0), {2, 0}, {4, 0}, {6, 0}, {6, 2},
                                            {6, 4},         {4, 4}, {2, 4}, {0, 4}, {0, 2}};
  for (const auto& xy : lamp_xy) {
    b.horizontal(xy.x() - 0.3, xy.x() + 0.3, xy.y() - 0.1, xy.y() + 0.1, H - 0.01, false, m_lamp);
    scene.lights.push_back({Vector3d(xy.x(), xy.y(), H - 0.2), 1.0});
  }
  scene.photometry.ambient = 0.12;
  scene.photometry.light_softening_m = 0.8;
  scene.photometry.exposure_key = 0.2;

  // Counter-clockwise loop with turns in place at the corners and a stop facing the blank
  // stretch of the north wall.
  using Kind = DriveSegment::Kind;
  const double v = 0.3;
  const double omega = deg_to_rad(40.0);
  const double quarter = kPi / 2;
  std::vector<DriveSegment> plan = {
      {Kind::kPause, 1.0, 0.0, 1.0},       {Kind::kStraight, 6.0, v, 1.0},    {Kind::kTurn, quarter, omega, 1.0},
      {Kind::kStraight, 4.0, v, 1.0},      {Kind::kTurn, quarter, omega, 1.0}, {Kind::kStraight, 3.0, v, 1.0},
      {Kind::kTurn, -quarter, omega, 1.0}, {Kind::kPause, 2.5, 0.0, 1.0},     {Kind::kTurn, quarter, omega, 1.0},
      {Kind::kStraight, 3.0, v, 1.0},      {Kind::kTurn, quarter, omega, 1.0}, {Kind::kStraight, 4.0, v, 1.0},
      {Kind::kTurn, quarter, omega, 1.0},  {Kind::kPause, 1.0, 0.0, 1.0}};
  DriveMotion motion(Vector2d(0.0, 0.0), 0.0, std::move(plan));
  scene.default_frames = static_cast<int>(std::floor(motion.period_s() * 30.0)) + 1;
  scene.motion = std::move(motion);
}

}  // namespace

Eigen::Matrix3d R_base_optical() {
  Eigen::Matrix3d R;
  // Columns: optical x (right) = base −y, optical y (down) = base −z, optical z = base x.
  R << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return R;
}

double SurfaceQuad::distance_m(const Eigen::Vector3d& p_m) const {
  const Vector3d d = p_m - center_m;
  const double s = std::max(std::abs(d.dot(axis_u)) - half_u_m, 0.0);
  const double r = std::max(std::abs(d.dot(axis_v)) - half_v_m, 0.0);
  const double h = d.dot(normal());
  return std::sqrt(s * s + r * r + h * h);
}

double SceneModel::period_s() const {
  if (const auto* drive_motion = drive()) return drive_motion->period_s();
  return std::get<HandheldMotion>(motion).period_s;
}

Eigen::Isometry3d SceneModel::T_world_base(double t_s) const {
  if (const auto* drive_motion = drive()) return drive_motion->T_world_base(t_s);
  return std::get<HandheldMotion>(motion).T_world_cam(t_s) * calibration.rgb.T_base_cam.inverse();
}

Eigen::Isometry3d SceneModel::T_world_rgb(double t_s) const {
  if (const auto* drive_motion = drive()) return drive_motion->T_world_base(t_s) * calibration.rgb.T_base_cam;
  return std::get<HandheldMotion>(motion).T_world_cam(t_s);
}

double SceneModel::distance_to_surface_m(const Eigen::Vector3d& p_world_m) const {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& quad : surfaces) best = std::min(best, quad.distance_m(p_world_m));
  return best;
}

std::optional<SceneModel> make_scene(const std::string& name, std::uint64_t seed, std::string* error) {
  SceneModel scene;
  scene.name = name;
  scene.description = scene_description(name);
  scene.calibration.source = "rankslam simulator, scene " + name;
  scene.calibration.depth_scale = 5000.0;
  scene.calibration.rgb = kinect_rgb(pose(R_base_optical(), Vector3d::Zero()));
  if (name == "office" || name == "dark-office") {
    build_office(scene, seed, name == "dark-office");
  } else if (name == "zigzag-plain") {
    build_zigzag(scene);
  } else if (name == "poster-wall") {
    build_poster_wall(scene, seed);
  } else if (name == "corridor-loop") {
    build_corridor(scene, seed);
    scene.calibration.rgb.T_base_cam = pose(R_base_optical(), Vector3d(0.15, 0.0, 0.5));
    hal::CameraCalibration fisheye;
    fisheye.model = hal::CameraModel::kFisheye;
    fisheye.width = 960;
    fisheye.height = 600;
    fisheye.fx = 230.0;
    fisheye.fy = 230.0;
    fisheye.cx = 479.5;
    fisheye.cy = 299.5;
    fisheye.distortion = {0.0129, 0.00266, -0.00587, 0.00126, 0.0};
    // Above the colour camera, pitched up 8° and yawed 2° left.
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(deg_to_rad(2.0), Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(deg_to_rad(-8.0), Vector3d::UnitY()))
                                  .toRotationMatrix() *
                              R_base_optical();
    fisheye.T_base_cam = pose(R, Vector3d(0.10, 0.02, 0.75));
    fisheye.T_base_cam_given = true;
    scene.calibration.fisheye = fisheye;
    scene.calibration.wheels = hal::WheelGeometry{};
  } else {
    if (error) *error = "unknown scene '" + name + "'";
    return std::nullopt;
  }
  return scene;
}

}  // namespace rankslam::sim
