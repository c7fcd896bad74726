#pragma once

#include "rankslam/sim/scene.hpp"

#include <opencv2/core/mat.hpp>

#include <cstdint>

namespace rankslam::sim::detail {

/// Procedural, tileable textures. Every generator is a pure function of its arguments.

/// Builds the mip pyramid and mean luminance of a CV_8UC3 image with power-of-two sides.
[[nodiscard]] Texture make_texture(cv::Mat level0, double texel_m);

/// Paint or plaster: `color_bgr` (0..1) with low-frequency blotches of relative amplitude
/// `strength` and a faint fine grain.
[[nodiscard]] Texture paint_texture(std::uint64_t seed, int size, double texel_m, cv::Vec3f color_bgr,
                                    float strength);
/// Carpet / floor: mottled noise at several scales around `color_bgr`.
[[nodiscard]] Texture carpet_texture(std::uint64_t seed, int size, double texel_m, cv::Vec3f color_bgr);
/// Wood grain along the texture's x axis.
[[nodiscard]] Texture wood_texture(std::uint64_t seed, int size, double texel_m, cv::Vec3f color_bgr);
/// Cardboard: fibre noise, tape and printed marks.
[[nodiscard]] Texture cardboard_texture(std::uint64_t seed, int size, double texel_m);
/// Whiteboard with marker strokes and writing.
[[nodiscard]] Texture whiteboard_texture(std::uint64_t seed, int size, double texel_m);
/// A grid of cells x cells independent posters (shapes, blobs, stripes, text, photo-like
/// noise); cell (i, j) spans texture pixels [i·size/cells, (i+1)·size/cells).
[[nodiscard]] Texture poster_atlas_texture(std::uint64_t seed, int size, int cells, double texel_m);
/// A whole wall of overlapping posters on a busy background (width × height texels).
[[nodiscard]] Texture poster_wall_texture(std::uint64_t seed, int width, int height, double texel_m);

}  // namespace rankslam::sim::detail
