#pragma once

#include "rankslam/camera/lens.hpp"
#include "rankslam/sim/scene.hpp"

#include <opencv2/core/mat.hpp>

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

namespace rankslam::sim::detail {

/// One texture mip level, flattened so a lookup needs no cv::Mat indirections.
struct TextureLevel {
  const std::uint8_t* texels = nullptr;  // BGRA, 4 bytes per texel
  int mask_u = 0, mask_v = 0, stride = 0;  // stride in texels
};

/// Pixel rays of one camera and the bounding cones of its 16×16 tiles, built once.
class CameraRays {
 public:
  static constexpr int kTile = 16;

  /// Pinhole: rays (x, y, 1) through pixel centres. Fisheye: unit rays of the equidistant
  /// model with k1..k4, pixels beyond `max_field_angle_rad` from the axis are invalid.
  CameraRays(const hal::CameraCalibration& camera, double max_field_angle_rad);

  static constexpr int kTilePixels = kTile * kTile;

  struct Cone {
    float ax = 0, ay = 0, az = 1;  // unit axis
    float cos_half = 1, sin_half = 0;
    bool any_valid = false;
    // Four planes through the centre with every ray of the tile on their positive side
    // (n·d ≥ 0); a quad with all corners behind one of them cannot be hit in this tile.
    bool has_planes = false;
    std::array<std::array<float, 3>, 4> planes{};
  };

  /// Ray through pixel (u, v) (any real coordinates), nullopt outside the fisheye's field.
  [[nodiscard]] std::optional<Eigen::Vector3d> unproject(double u, double v) const;

  int width = 0;
  int height = 0;
  bool pinhole = true;
  int tiles_x = 0;
  int tiles_y = 0;
  std::vector<float> dx, dy, dz;  // per pixel; (0, 0, 0) for invalid pixels
  // The same rays tile by tile (kTilePixels per tile, row-major inside the tile, padded with
  // zero rays), so the caster's inner loop runs over contiguous arrays.
  std::vector<float> tile_dx, tile_dy, tile_dz;
  std::vector<float> inv_norm;    // 1 / |d|
  std::vector<std::uint8_t> valid;
  std::vector<Cone> tiles;
  double frame_half_angle_rad = 0.0;  // cone around +z containing every ray
  float pixel_angle_rad = 0.0f;       // angle subtended by one pixel near the centre

 private:
  hal::CameraCalibration camera_;
  camera::Lens lens_;
};

/// One scene quad seen from one camera pose, in camera coordinates (float for speed).
struct ViewQuad {
  float nx, ny, nz, plane;  // normal and c·n (< 0: the camera is on the visible side)
  float ux, uy, uz, cu;     // axis_u and c·axis_u
  float vx, vy, vz, cv;     // axis_v and c·axis_v
  float hu, hv;             // half extents with a seam tolerance
  float cx, cy, cz, radius; // bounding sphere
  std::array<std::array<float, 3>, 4> corners;
  int quad;                 // index into SceneModel::surfaces
};

/// The quads a camera can see from one pose. Capacity is reserved at set-up.
struct View {
  std::vector<ViewQuad> quads;
};

/// Per-thread scratch for one band of 16 rows; sized at set-up, reused every frame.
struct BandWorkspace {
  explicit BandWorkspace(int max_width, std::size_t max_quads);
  std::vector<float> t, s, r;            // nearest hit: ray parameter and quad coordinates
  std::vector<std::int32_t> hit;         // ViewQuad index or −1
  std::vector<float> acc;                // B, G, R, IR per pixel (interleaved)
  std::vector<std::uint8_t> shadowed;    // not lit by the IR projector
  std::vector<std::uint16_t> candidates; // quads that may be hit inside one tile
  // Nearest hit per pixel of the tile being cast.
  std::array<float, CameraRays::kTilePixels> tile_t{}, tile_s{}, tile_r{};
  std::array<std::int32_t, CameraRays::kTilePixels> tile_hit{};
};

/// Images of one RGB-D frame (rows of these are written by bands in parallel).
struct RgbdImages {
  cv::Mat rgb;    // CV_8UC3
  cv::Mat depth;  // CV_16UC1
  cv::Mat ir;     // CV_8UC1, empty without IR
};

/// Renders colour, depth and IR from the scene with the sensor models of the Kinect, and the
/// wide-angle camera. Set-up (constructor) allocates; band rendering does not.
class Renderer {
 public:
  struct Settings {
    std::uint64_t seed = 1;
    bool sensor_noise = true;
    double min_depth_m = 0.5;
    double max_depth_m = 4.5;
    int threads = 1;  // for baking at set-up
  };

  Renderer(const SceneModel& scene, const Settings& settings);

  [[nodiscard]] const CameraRays& rgb_rays() const { return rgb_rays_; }
  [[nodiscard]] const CameraRays* fisheye_rays() const { return fisheye_rays_.empty() ? nullptr : &fisheye_rays_[0]; }
  [[nodiscard]] std::size_t quad_count() const { return scene_.surfaces.size(); }

  /// Culls and transforms the scene into camera coordinates for a camera pose.
  void prepare_view(const CameraRays& rays, const Eigen::Isometry3d& T_world_cam, View& view) const;

  /// Renders rows [band·16, band·16 + 16) of an RGB-D frame. `views` are the sub-exposure
  /// poses (one without motion blur); depth comes from views[views.size() / 2].
  void render_rgbd_band(const std::vector<View>& views, int band, std::uint64_t frame, RgbdImages& out,
                        BandWorkspace& ws) const;
  /// Renders rows of a fisheye frame (CV_8UC3).
  void render_fisheye_band(const std::vector<View>& views, int band, std::uint64_t frame, cv::Mat& out,
                           BandWorkspace& ws) const;

 private:
  struct QuadShading {
    const Texture* texture = nullptr;
    const TextureLevel* levels = nullptr;  // into texture_levels_
    float origin_u = 0, origin_v = 0;  // texture metres at s = 0, r = 0
    std::array<float, 4> albedo{};    // B, G, R, 0
    std::array<float, 4> emission{};  // B, G, R, 0
    float ir_reflectance = 0, ir_contrast = 0, inv_mean_gray = 1;
    float inv_texel = 1, inv_texel2 = 1;
    int max_level = 0;
    std::uint32_t lightmap = 0;  // offset into lightmap_
    int lm_nu = 2, lm_nv = 2;
    float lm_inv_step_u = 1, lm_inv_step_v = 1, half_u = 0, half_v = 0;
  };

  void bake_lightmaps(int threads);
  void build_speckle_pattern();
  // Nearest hit for every pixel of rows [y0, y0 + rows) into the workspace.
  void cast_band(const CameraRays& rays, const View& view, int y0, int rows, BandWorkspace& ws) const;
  // Adds shaded colour (and IR) of the cast hits to the accumulators (assign when `first`).
  void shade_band(const CameraRays& rays, const View& view, int y0, int rows, bool first, bool with_ir,
                  BandWorkspace& ws) const;
  void projector_shadow(const CameraRays& rays, int y0, int rows, BandWorkspace& ws) const;
  void write_depth(const CameraRays& rays, const View& view, int y0, int rows, std::uint64_t frame, cv::Mat& depth,
                   const BandWorkspace& ws) const;
  void write_color(int width, int y0, int rows, float scale, std::uint64_t key, cv::Mat& image,
                   const BandWorkspace& ws) const;

  const SceneModel& scene_;
  Settings settings_;
  CameraRays rgb_rays_;
  std::vector<CameraRays> fisheye_rays_;  // zero or one
  std::vector<QuadShading> shading_;
  std::vector<TextureLevel> texture_levels_;
  std::vector<float> lightmap_;
  std::vector<float> speckle_;  // projector dot pattern, speckle_width_ × height
  int speckle_width_ = 0;
  int speckle_offset_ = 0;
  static constexpr int kLinearSteps = 4096;  // linear sensor value 0..1 in 4096 steps
  static constexpr int kNoiseSteps = 256;     // standard normal quantiles per step
  // 8-bit colour output for (linear step, noise quantile): gamma, read + shot noise, rounding.
  std::vector<std::uint8_t> color_lut_;
  std::array<std::uint8_t, kLinearSteps> clean_lut_{};
  std::array<float, 4096> gaussian_{};  // standard normal quantiles (depth and IR noise)
  float exposure_ = 1.0f;
  float fisheye_exposure_ = 1.0f;
  float fb_projector_px_ = 0.0f;  // focal · projector baseline, pixels·metres (IR image)
};

}  // namespace rankslam::sim::detail
