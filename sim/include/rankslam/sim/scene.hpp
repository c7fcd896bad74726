#pragma once

#include "rankslam/hal/calibration.hpp"
#include "rankslam/sim/motion.hpp"

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <variant>
#include <vector>

namespace rankslam::sim {

/// A one-sided rectangle, visible from the side its normal (axis_u × axis_v) points to.
/// Local coordinates (s, r) run along axis_u and axis_v from the centre.
struct SurfaceQuad {
  Eigen::Vector3d center_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis_u = Eigen::Vector3d::UnitX();  ///< Unit; "right" on the texture.
  Eigen::Vector3d axis_v = Eigen::Vector3d::UnitY();  ///< Unit, ⟂ axis_u; "up" on the texture.
  double half_u_m = 0.5;
  double half_v_m = 0.5;
  int material = 0;
  /// Texture position (metres, x right, y down) of the quad's top-left corner (s = −half_u,
  /// r = +half_v); pieces of one split surface continue each other's texture.
  Eigen::Vector2d texture_origin_m = Eigen::Vector2d::Zero();

  [[nodiscard]] Eigen::Vector3d normal() const { return axis_u.cross(axis_v); }
  /// Euclidean distance from `p_m` to the rectangle.
  [[nodiscard]] double distance_m(const Eigen::Vector3d& p_m) const;
};

/// A tiling colour texture (power-of-two sides) with its mip pyramid.
struct Texture {
  std::vector<cv::Mat> levels;  ///< CV_8UC4 BGRA; level k has half the sides of level k−1.
  double texel_m = 0.002;       ///< Surface size of one level-0 texel.
  float mean_gray = 0.5f;       ///< Mean luminance of level 0, 0..1.
};

/// Lambertian surface appearance. Reflectances are linear, 0..1.
struct Material {
  std::string name;
  Eigen::Vector3f albedo_bgr = Eigen::Vector3f::Constant(0.6f);  ///< Multiplies the texture.
  int texture = -1;                   ///< Index into SceneModel::textures; −1 = uniform.
  float emission = 0.0f;              ///< Self-luminance added to the shading (lamps).
  float ir_reflectance = 0.6f;        ///< Mean near-infrared reflectance.
  float ir_texture_contrast = 0.8f;   ///< How strongly the texture's luminance shows in IR.
};

/// Ceiling-type point lamp; irradiance = intensity·(1 + cos γ)/2·cos(incidence)/(d² + softening²)
/// with γ the angle from straight down at the lamp.
struct PointLight {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  double intensity = 1.0;
};

/// Exposure and sensor noise of the simulated cameras.
struct Photometry {
  double ambient = 0.15;           ///< Irradiance reaching every surface.
  double light_softening_m = 0.6;  ///< Keeps lamps from blowing out nearby surfaces.
  /// Fixed exposure, set once per scene: radiance is scaled so the area-weighted mean of
  /// albedo × irradiance over all surfaces reads this linear value (0.18 = mid grey).
  double exposure_key = 0.18;
  double read_noise_levels = 1.2;  ///< Gaussian noise σ in 8-bit levels.
  double shot_noise_gain = 0.04;   ///< Additional variance per 8-bit level of signal.
  double fisheye_exposure = 1.0;   ///< Relative exposure of the wide-angle camera.
  /// IR: projector irradiance at 1 m and normal incidence, and ambient IR irradiance.
  double ir_projector_power = 1.0;
  double ir_ambient = 0.02;
  double ir_gain = 1800.0;         ///< IR radiance → 8-bit levels.
  double ir_read_noise_levels = 2.0;
};

/// Everything that defines one simulated scene: surfaces, appearance, lamps, rig, motion.
/// Built deterministically from (name, seed); the seed changes textures only.
struct SceneModel {
  std::string name;
  std::string description;
  int default_frames = 300;
  std::vector<SurfaceQuad> surfaces;  ///< Large surfaces are already split into pieces ≤ ~1 m.
  std::vector<Material> materials;
  std::vector<Texture> textures;
  std::vector<PointLight> lights;
  Photometry photometry;
  /// Colour camera (depth and IR registered to it), optional fisheye and wheel geometry.
  hal::Calibration calibration;
  bool has_ir = false;
  /// Hand-held scenes move the camera; wheeled scenes drive the base.
  std::variant<HandheldMotion, DriveMotion> motion;

  [[nodiscard]] double period_s() const;
  /// Rig / robot base in the world; for hand-held scenes the base is the camera with
  /// base axes (x forward, y left, z up).
  [[nodiscard]] Eigen::Isometry3d T_world_base(double t_s) const;
  /// Colour (= depth) camera optical frame in the world: what groundtruth.txt holds.
  [[nodiscard]] Eigen::Isometry3d T_world_rgb(double t_s) const;
  [[nodiscard]] const DriveMotion* drive() const { return std::get_if<DriveMotion>(&motion); }
  /// Distance from a world point to the nearest surface.
  [[nodiscard]] double distance_to_surface_m(const Eigen::Vector3d& p_world_m) const;
};

/// Builds scene `name` (one of scene_names()). Returns nullopt with `error` set for an unknown
/// name.
[[nodiscard]] std::optional<SceneModel> make_scene(const std::string& name, std::uint64_t seed,
                                                   std::string* error);

/// Rotation taking camera optical axes (x right, y down, z forward) to base axes (x forward,
/// y left, z up).
[[nodiscard]] Eigen::Matrix3d R_base_optical();

}  // namespace rankslam::sim
