#include "texture.hpp"

#include "random.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

namespace rankslam::sim::detail {
namespace {

// Runs fn(y) for every row; rows are independent, so splitting them across threads leaves the
// result unchanged.
template <typename Fn>
void for_rows(int rows, Fn&& fn) {
  const int threads = std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 8);
  if (threads == 1 || rows < 64) {
    for (int y = 0; y < rows; ++y) fn(y);
    return;
  }
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&, t] {
      for (int y = t; y < rows; y += threads) fn(y);
    });
  }
  for (auto& thread : pool) thread.join();
}

constexpr float kTwoPi = 2.0f * std::numbers::pi_v<float>;

// Value noise on a lattice that wraps every `period` cells (a power of two), so textures tile
// seamlessly.
class PeriodicNoise {
 public:
  PeriodicNoise(std::uint64_t seed, int period) {
    period_ = 1;
    while (period_ < period) period_ *= 2;
    mask_ = period_ - 1;
    values_.resize(static_cast<std::size_t>(period_) * static_cast<std::size_t>(period_));
    const std::uint64_t key = stream_key(seed, 0x4e4f495345ULL, static_cast<std::uint64_t>(period_));
    for (std::size_t i = 0; i < values_.size(); ++i) {
      values_[i] = static_cast<float>(element_hash(key, i) >> 40U) * 0x1.0p-24f;
    }
  }
  // x, y in lattice cells; smooth (C1) interpolation between lattice values.
  [[nodiscard]] float at(float x, float y) const {
    const int ix = fast_floor(x);
    const int iy = fast_floor(y);
    float ax = x - static_cast<float>(ix);
    float ay = y - static_cast<float>(iy);
    ax = ax * ax * (3.0f - 2.0f * ax);
    ay = ay * ay * (3.0f - 2.0f * ay);
    const int x0 = ix & mask_;
    const int y0 = iy & mask_;
    const int x1 = (ix + 1) & mask_;
    const int y1 = (iy + 1) & mask_;
    const float* row0 = values_.data() + static_cast<std::size_t>(y0 * period_);
    const float* row1 = values_.data() + static_cast<std::size_t>(y1 * period_);
    const float top = row0[x0] + (row0[x1] - row0[x0]) * ax;
    const float bottom = row1[x0] + (row1[x1] - row1[x0]) * ax;
    return top + (bottom - top) * ay;
  }
  [[nodiscard]] int period() const { return period_; }

 private:
  static int fast_floor(float x) {
    const int i = static_cast<int>(x);
    return i - (x < static_cast<float>(i) ? 1 : 0);
  }
  int period_ = 1;
  int mask_ = 0;
  std::vector<float> values_;
};

// Fractal sum of octaves; u, v are texture coordinates in [0, 1), the result is in [0, 1].
class Fbm {
 public:
  Fbm(std::uint64_t seed, int base_period, int octaves, float persistence = 0.5f) {
    float amplitude = 1.0f;
    for (int o = 0; o < octaves; ++o) {
      octaves_.emplace_back(seed + static_cast<std::uint64_t>(o) * 7919U, base_period << o);
      amplitudes_.push_back(amplitude);
      total_ += amplitude;
      amplitude *= persistence;
    }
  }
  [[nodiscard]] float at(float u, float v) const {
    float sum = 0.0f;
    for (std::size_t o = 0; o < octaves_.size(); ++o) {
      const auto period = static_cast<float>(octaves_[o].period());
      sum += amplitudes_[o] * octaves_[o].at(u * period, v * period);
    }
    return sum / total_;
  }

 private:
  std::vector<PeriodicNoise> octaves_;
  std::vector<float> amplitudes_;
  float total_ = 0.0f;
};

// Per-texel white noise in [-1, 1].
float grain(std::uint64_t key, int x, int y) {
  const std::uint64_t h = element_hash(key, (static_cast<std::uint64_t>(y) << 32U) | static_cast<std::uint32_t>(x));
  return static_cast<float>(h >> 40U) * 0x1.0p-23f - 1.0f;
}

cv::Vec3b to_bgr8(float b, float g, float r) {
  auto q = [](float v) { return static_cast<std::uint8_t>(std::clamp(v * 255.0f + 0.5f, 0.0f, 255.0f)); };
  return {q(b), q(g), q(r)};
}

cv::Scalar random_color(Rng& rng, double min_value = 0.25, double min_saturation = 0.35) {
  const double h = rng.uniform(0.0, 6.0);
  const double s = rng.uniform(min_saturation, 1.0);
  const double v = rng.uniform(min_value, 1.0);
  const double c = v * s;
  const double x = c * (1.0 - std::abs(std::fmod(h, 2.0) - 1.0));
  const double m = v - c;
  double r = 0;
  double g = 0;
  double b = 0;
  switch (static_cast<int>(h)) {
    case 0: r = c; g = x; break;
    case 1: r = x; g = c; break;
    case 2: g = c; b = x; break;
    case 3: g = x; b = c; break;
    case 4: r = x; b = c; break;
    default: r = c; b = x; break;
  }
  return cv::Scalar((b + m) * 255.0, (g + m) * 255.0, (r + m) * 255.0);
}

cv::Scalar random_gray(Rng& rng, double lo, double hi) {
  const double v = rng.uniform(lo, hi) * 255.0;
  return cv::Scalar(v, v, v);
}

std::string random_word(Rng& rng, int min_length, int max_length) {
  static constexpr char kLetters[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
  const int length = rng.integer(min_length, max_length);
  std::string word;
  for (int i = 0; i < length; ++i) word += kLetters[rng.integer(0, static_cast<int>(sizeof kLetters) - 2)];
  return word;
}

cv::Point random_point(Rng& rng, const cv::Rect& area) {
  return {area.x + rng.integer(0, std::max(area.width - 1, 0)), area.y + rng.integer(0, std::max(area.height - 1, 0))};
}

// Text lines of random words, as on printed matter.
void draw_text_block(cv::Mat& image, Rng& rng, const cv::Rect& area, const cv::Scalar& color, int lines,
                     double scale) {
  const int fonts[] = {cv::FONT_HERSHEY_SIMPLEX, cv::FONT_HERSHEY_DUPLEX, cv::FONT_HERSHEY_COMPLEX,
                       cv::FONT_HERSHEY_TRIPLEX, cv::FONT_HERSHEY_PLAIN};
  const int font = fonts[rng.integer(0, 4)];
  const int thickness = std::max(1, static_cast<int>(scale * rng.uniform(1.0, 2.5)));
  int baseline = 0;
  const int line_height = cv::getTextSize("Ag", font, scale, thickness, &baseline).height * 2;
  int y = area.y + line_height;
  for (int l = 0; l < lines && y < area.y + area.height; ++l, y += line_height) {
    std::string text = random_word(rng, 2, 8);
    while (cv::getTextSize(text, font, scale, thickness, &baseline).width < area.width * rng.uniform(0.4, 0.95)) {
      text += ' ';
      text += random_word(rng, 1, 7);
    }
    cv::putText(image, text, {area.x, y}, font, scale, color, thickness, cv::LINE_AA);
  }
}

// One poster: gradient background, large shapes, blobs, stripes, text and a photo-like patch.
void draw_poster(cv::Mat& image, const cv::Rect& area, Rng& rng) {
  cv::Mat roi = image(area);
  const cv::Scalar c0 = random_color(rng, 0.3);
  const cv::Scalar c1 = random_color(rng, 0.3);
  for (int y = 0; y < roi.rows; ++y) {
    const double a = static_cast<double>(y) / std::max(roi.rows - 1, 1);
    const cv::Scalar c = c0 * (1.0 - a) + c1 * a;
    roi.row(y).setTo(c);
  }
  const int w = roi.cols;
  const int h = roi.rows;
  const cv::Rect whole(0, 0, w, h);
  // Photo-like patch: smooth colour noise.
  if (rng.chance(0.7)) {
    const cv::Rect patch(rng.integer(0, w / 3), rng.integer(0, h / 3), rng.integer(w / 4, w / 2),
                         rng.integer(h / 4, h / 2));
    const Fbm noise_b(rng.next(), 3, 5);
    const Fbm noise_g(rng.next(), 3, 5);
    const Fbm noise_r(rng.next(), 3, 5);
    for (int y = patch.y; y < std::min(patch.y + patch.height, h); ++y) {
      for (int x = patch.x; x < std::min(patch.x + patch.width, w); ++x) {
        const float u = static_cast<float>(x) / static_cast<float>(w);
        const float v = static_cast<float>(y) / static_cast<float>(h);
        roi.at<cv::Vec3b>(y, x) = to_bgr8(1.6f * noise_b.at(u, v) - 0.3f, 1.6f * noise_g.at(u, v) - 0.3f,
                                          1.6f * noise_r.at(u, v) - 0.3f);
      }
    }
  }
  // Large shapes.
  const int shapes = rng.integer(3, 7);
  for (int i = 0; i < shapes; ++i) {
    const cv::Scalar color = random_color(rng, 0.15);
    const int kind = rng.integer(0, 2);
    const cv::Point p = random_point(rng, whole);
    const int size = rng.integer(w / 10, w / 3);
    if (kind == 0) {
      cv::rectangle(roi, cv::Rect(p.x, p.y, size, rng.integer(size / 3, size)), color, cv::FILLED, cv::LINE_AA);
    } else if (kind == 1) {
      cv::circle(roi, p, size / 2, color, cv::FILLED, cv::LINE_AA);
    } else {
      const cv::Point pts[] = {p, p + cv::Point(size, rng.integer(-size / 2, size / 2)),
                               p + cv::Point(rng.integer(-size / 2, size / 2), size)};
      cv::fillConvexPoly(roi, pts, 3, color, cv::LINE_AA);
    }
  }
  // Blobs.
  const int blobs = rng.integer(8, 24);
  for (int i = 0; i < blobs; ++i) {
    cv::circle(roi, random_point(rng, whole), rng.integer(std::max(2, w / 100), std::max(3, w / 14)),
               random_color(rng, 0.1), cv::FILLED, cv::LINE_AA);
  }
  // Stripes.
  if (rng.chance(0.7)) {
    const cv::Rect block(rng.integer(0, w / 2), rng.integer(0, h / 2), rng.integer(w / 5, w / 2),
                         rng.integer(h / 6, h / 3));
    const cv::Scalar color = random_color(rng, 0.1);
    const int spacing = rng.integer(std::max(4, w / 60), std::max(6, w / 20));
    const double angle = rng.uniform(0.0, std::numbers::pi);
    const cv::Point2d dir(std::cos(angle), std::sin(angle));
    const cv::Point2d normal(-dir.y, dir.x);
    cv::Mat block_roi = roi(block & whole);
    const double extent = block.width + block.height;
    for (double offset = -extent; offset < extent; offset += spacing) {
      const cv::Point2d centre = cv::Point2d(block.width / 2.0, block.height / 2.0) + normal * offset;
      cv::line(block_roi, centre - dir * extent, centre + dir * extent, color, std::max(1, spacing / 3), cv::LINE_AA);
    }
  }
  // Text.
  const cv::Scalar ink = rng.chance(0.5) ? random_gray(rng, 0.0, 0.15) : random_gray(rng, 0.85, 1.0);
  draw_text_block(roi, rng, cv::Rect(w / 12, rng.integer(h / 2, 3 * h / 4), w - w / 6, h / 4), ink,
                  rng.integer(2, 5), std::max(0.4, w / 700.0 * rng.uniform(0.8, 1.6)));
  cv::putText(roi, random_word(rng, 3, 7), {w / 14, h / 6}, cv::FONT_HERSHEY_DUPLEX, std::max(0.6, w / 260.0),
              random_color(rng, 0.0, 0.0), std::max(2, w / 120), cv::LINE_AA);
  cv::rectangle(roi, whole, random_gray(rng, 0.9, 1.0), std::max(2, w / 60));
}

// Multiplies every texel by a slow mottle and a fine grain (printing and paper).
void add_print_grain(cv::Mat& image, std::uint64_t seed, float mottle, float fine) {
  const Fbm noise(seed, 8, 4);
  const std::uint64_t key = stream_key(seed, 0x6772ULL, 0);
  for_rows(image.rows, [&](int y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < image.cols; ++x) {
      const float u = static_cast<float>(x) / static_cast<float>(image.cols);
      const float v = static_cast<float>(y) / static_cast<float>(image.rows);
      const float gain = 1.0f + mottle * (2.0f * noise.at(u, v) - 1.0f) + fine * grain(key, x, y);
      for (int c = 0; c < 3; ++c) {
        row[x][c] = static_cast<std::uint8_t>(std::clamp(static_cast<float>(row[x][c]) * gain + 0.5f, 0.0f, 255.0f));
      }
    }
  });
}

}  // namespace

Texture make_texture(cv::Mat level0, double texel_m) {
  Texture texture;
  texture.texel_m = texel_m;
  double sum = 0.0;
  for (int y = 0; y < level0.rows; ++y) {
    const auto* row = level0.ptr<cv::Vec3b>(y);
    double row_sum = 0.0;
    for (int x = 0; x < level0.cols; ++x) row_sum += 0.114 * row[x][0] + 0.587 * row[x][1] + 0.299 * row[x][2];
    sum += row_sum;
  }
  texture.mean_gray = static_cast<float>(sum / (255.0 * static_cast<double>(level0.total())));
  // Four bytes per texel so the renderer fetches a texel with one 32-bit load.
  cv::Mat bgra(level0.rows, level0.cols, CV_8UC4);
  for (int y = 0; y < level0.rows; ++y) {
    const auto* src = level0.ptr<cv::Vec3b>(y);
    auto* dst = bgra.ptr<cv::Vec4b>(y);
    for (int x = 0; x < level0.cols; ++x) dst[x] = cv::Vec4b(src[x][0], src[x][1], src[x][2], 255);
  }
  texture.levels.push_back(bgra);
  // Box-filtered mip levels down to 8 texels, exact integer averages.
  while (texture.levels.back().cols > 8 && texture.levels.back().rows > 8) {
    const cv::Mat& src = texture.levels.back();
    cv::Mat dst(src.rows / 2, src.cols / 2, CV_8UC4);
    for (int y = 0; y < dst.rows; ++y) {
      const auto* a = src.ptr<cv::Vec4b>(2 * y);
      const auto* b = src.ptr<cv::Vec4b>(2 * y + 1);
      auto* d = dst.ptr<cv::Vec4b>(y);
      for (int x = 0; x < dst.cols; ++x) {
        for (int c = 0; c < 4; ++c) {
          d[x][c] = static_cast<std::uint8_t>((a[2 * x][c] + a[2 * x + 1][c] + b[2 * x][c] + b[2 * x + 1][c] + 2) / 4);
        }
      }
    }
    texture.levels.push_back(dst);
  }
  return texture;
}

Texture paint_texture(std::uint64_t seed, int size, double texel_m, cv::Vec3f color_bgr, float strength) {
  cv::Mat image(size, size, CV_8UC3);
  const Fbm blotches(seed, 4, 5);
  const std::uint64_t key = stream_key(seed, 0x7061ULL, 0);
  for_rows(size, [&](int y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size; ++x) {
      const float u = static_cast<float>(x) / static_cast<float>(size);
      const float v = static_cast<float>(y) / static_cast<float>(size);
      const float gain = 1.0f + strength * (2.0f * blotches.at(u, v) - 1.0f) + 0.2f * strength * grain(key, x, y);
      row[x] = to_bgr8(color_bgr[0] * gain, color_bgr[1] * gain, color_bgr[2] * gain);
    }
  });
  return make_texture(image, texel_m);
}

Texture carpet_texture(std::uint64_t seed, int size, double texel_m, cv::Vec3f color_bgr) {
  cv::Mat image(size, size, CV_8UC3);
  const Fbm mottle(seed, 8, 5, 0.6f);
  const Fbm hue(seed + 17, 4, 3);
  const std::uint64_t key = stream_key(seed, 0x6361ULL, 0);
  for_rows(size, [&](int y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size; ++x) {
      const float u = static_cast<float>(x) / static_cast<float>(size);
      const float v = static_cast<float>(y) / static_cast<float>(size);
      const float gain = 0.55f + 0.9f * mottle.at(u, v) + 0.18f * grain(key, x, y);
      const float shift = 0.25f * (hue.at(u, v) - 0.5f);
      row[x] = to_bgr8(color_bgr[0] * gain * (1.0f + shift), color_bgr[1] * gain, color_bgr[2] * gain * (1.0f - shift));
    }
  });
  return make_texture(image, texel_m);
}

Texture wood_texture(std::uint64_t seed, int size, double texel_m, cv::Vec3f color_bgr) {
  cv::Mat image(size, size, CV_8UC3);
  const Fbm warp(seed, 2, 4);
  const Fbm fibres(seed + 5, 4, 3);
  const std::uint64_t key = stream_key(seed, 0x776fULL, 0);
  const float rings = 24.0f;
  for_rows(size, [&](int y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size; ++x) {
      const float u = static_cast<float>(x) / static_cast<float>(size);
      const float v = static_cast<float>(y) / static_cast<float>(size);
      // Rings run along x; the warp bends them like grain around knots.
      const float phase = rings * v + 2.5f * warp.at(u, v);
      const float ring = 0.5f + 0.5f * std::sin(kTwoPi * phase);
      const float streak = fibres.at(u * 0.25f, v * 4.0f);
      const float gain = 0.7f + 0.35f * ring * ring + 0.25f * (streak - 0.5f) + 0.05f * grain(key, x, y);
      row[x] = to_bgr8(color_bgr[0] * gain, color_bgr[1] * gain, color_bgr[2] * gain);
    }
  });
  return make_texture(image, texel_m);
}

Texture cardboard_texture(std::uint64_t seed, int size, double texel_m) {
  cv::Mat image(size, size, CV_8UC3);
  const Fbm mottle(seed, 6, 4);
  const std::uint64_t key = stream_key(seed, 0x6362ULL, 0);
  for_rows(size, [&](int y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size; ++x) {
      const float u = static_cast<float>(x) / static_cast<float>(size);
      const float v = static_cast<float>(y) / static_cast<float>(size);
      const float gain = 0.85f + 0.3f * mottle.at(u, v) + 0.06f * grain(key, x, y);
      row[x] = to_bgr8(0.30f * gain, 0.47f * gain, 0.62f * gain);
    }
  });
  Rng rng(seed ^ 0xca7dULL);
  const int s = size;
  // Packing tape across the middle, printed handling marks and a shipping label.
  cv::rectangle(image, cv::Rect(0, s / 2 - s / 20, s, s / 10), cv::Scalar(70, 140, 185), cv::FILLED);
  for (int i = 0; i < 3; ++i) {
    const cv::Point p(rng.integer(s / 10, 8 * s / 10), rng.integer(s / 10, 8 * s / 10));
    const int k = rng.integer(s / 20, s / 10);
    cv::arrowedLine(image, p + cv::Point(0, k), p - cv::Point(0, k), cv::Scalar(30, 30, 35), std::max(2, s / 100),
                    cv::LINE_AA, 0, 0.4);
  }
  draw_text_block(image, rng, cv::Rect(s / 10, s / 12, 8 * s / 10, s / 4), cv::Scalar(25, 25, 30), 2, s / 400.0);
  const cv::Rect label(rng.integer(s / 10, s / 2), rng.integer(6 * s / 10, 7 * s / 10), s / 3, s / 5);
  cv::rectangle(image, label, cv::Scalar(235, 240, 240), cv::FILLED);
  for (int x = label.x + 6; x < label.x + label.width / 2; x += rng.integer(2, 5)) {
    cv::line(image, {x, label.y + label.height / 2}, {x, label.y + label.height - 6}, cv::Scalar(20, 20, 20),
             rng.integer(1, 2));
  }
  draw_text_block(image, rng, cv::Rect(label.x + 4, label.y, label.width - 8, label.height / 2), cv::Scalar(20, 20, 20),
                  2, s / 1400.0);
  add_print_grain(image, seed + 3, 0.0f, 0.03f);
  return make_texture(image, texel_m);
}

Texture whiteboard_texture(std::uint64_t seed, int size, double texel_m) {
  cv::Mat image(size, size, CV_8UC3);
  const Fbm smudge(seed, 4, 4);
  for_rows(size, [&](int y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < size; ++x) {
      const float g = 0.86f + 0.06f * smudge.at(static_cast<float>(x) / static_cast<float>(size),
                                                 static_cast<float>(y) / static_cast<float>(size));
      row[x] = to_bgr8(g, g, g * 0.98f);
    }
  });
  Rng rng(seed ^ 0xb0a7dULL);
  const cv::Scalar inks[] = {cv::Scalar(40, 30, 30), cv::Scalar(150, 40, 20), cv::Scalar(40, 40, 170),
                             cv::Scalar(40, 120, 30)};
  const int s = size;
  for (int i = 0; i < 7; ++i) {
    const cv::Scalar ink = inks[rng.integer(0, 3)];
    const int kind = rng.integer(0, 3);
    const cv::Point p(rng.integer(s / 10, 8 * s / 10), rng.integer(s / 10, 8 * s / 10));
    const int thickness = std::max(2, s / 250);
    if (kind == 0) {
      draw_text_block(image, rng, cv::Rect(p.x, p.y, s / 3, s / 6), ink, rng.integer(2, 4), s / 900.0);
    } else if (kind == 1) {
      cv::rectangle(image, cv::Rect(p.x, p.y, rng.integer(s / 12, s / 5), rng.integer(s / 15, s / 6)), ink, thickness,
                    cv::LINE_AA);
    } else if (kind == 2) {
      cv::arrowedLine(image, p, p + cv::Point(rng.integer(-s / 5, s / 5), rng.integer(-s / 8, s / 8)), ink, thickness,
                      cv::LINE_AA);
    } else {
      // A free-hand curve.
      std::vector<cv::Point> curve;
      double angle = rng.uniform(0.0, 2.0 * std::numbers::pi);
      cv::Point2d q(p);
      for (int k = 0; k < 40; ++k) {
        angle += rng.uniform(-0.5, 0.5);
        q += cv::Point2d(std::cos(angle), std::sin(angle)) * (s / 150.0);
        curve.emplace_back(q);
      }
      cv::polylines(image, curve, false, ink, thickness, cv::LINE_AA);
    }
  }
  return make_texture(image, texel_m);
}

Texture poster_atlas_texture(std::uint64_t seed, int size, int cells, double texel_m) {
  cv::Mat image(size, size, CV_8UC3, cv::Scalar(200, 200, 200));
  Rng rng(seed ^ 0x905e7ULL);
  const int cell = size / cells;
  for (int j = 0; j < cells; ++j) {
    for (int i = 0; i < cells; ++i) draw_poster(image, cv::Rect(i * cell, j * cell, cell, cell), rng);
  }
  add_print_grain(image, seed + 11, 0.06f, 0.05f);
  return make_texture(image, texel_m);
}

Texture poster_wall_texture(std::uint64_t seed, int width, int height, double texel_m) {
  cv::Mat image(height, width, CV_8UC3);
  // Background: coloured plaster-like noise, so the gaps between posters carry texture too.
  // Detail in the brightness, slower variation in the hue.
  const Fbm brightness(seed + 1, 8, 5, 0.6f);
  const Fbm hue_a(seed + 2, 8, 3);
  const Fbm hue_b(seed + 3, 8, 3);
  for_rows(height, [&](int y) {
    auto* row = image.ptr<cv::Vec3b>(y);
    for (int x = 0; x < width; ++x) {
      const float u = static_cast<float>(x) / static_cast<float>(width);
      const float v = static_cast<float>(y) / static_cast<float>(height);
      const float l = 0.15f + 0.9f * brightness.at(u, v);
      const float a = 1.6f * (hue_a.at(u, v) - 0.5f);
      const float b = 1.6f * (hue_b.at(u, v) - 0.5f);
      row[x] = to_bgr8(l * (1.0f + a), l * (1.0f - 0.5f * a + 0.5f * b), l * (1.0f - b));
    }
  });
  Rng rng(seed ^ 0x3a11ULL);
  // Posters of varied size on a jittered grid, some overlapping.
  const int columns = 7;
  const int rows = std::max(2, columns * height / width);
  for (int j = 0; j < rows; ++j) {
    for (int i = 0; i < columns; ++i) {
      const int w = rng.integer(width / 11, width / 6);
      const int h = rng.integer(w * 3 / 4, w * 3 / 2);
      const int x = i * width / columns + rng.integer(-width / 40, width / 40);
      const int y = j * height / rows + rng.integer(-height / 40, height / 40);
      const cv::Rect area = cv::Rect(x, y, w, h) & cv::Rect(0, 0, width, height);
      if (area.width > 16 && area.height > 16) draw_poster(image, area, rng);
    }
  }
  // Stickers and sprayed tags between the posters.
  for (int i = 0; i < 120; ++i) {
    cv::circle(image, random_point(rng, cv::Rect(0, 0, width, height)), rng.integer(4, 30), random_color(rng, 0.2),
               cv::FILLED, cv::LINE_AA);
  }
  for (int i = 0; i < 25; ++i) {
    std::vector<cv::Point> curve;
    cv::Point2d q(random_point(rng, cv::Rect(0, 0, width, height)));
    double angle = rng.uniform(0.0, 2.0 * std::numbers::pi);
    for (int k = 0; k < 60; ++k) {
      angle += rng.uniform(-0.6, 0.6);
      q += cv::Point2d(std::cos(angle), std::sin(angle)) * 6.0;
      curve.emplace_back(q);
    }
    cv::polylines(image, curve, false, random_color(rng, 0.1), rng.integer(3, 8), cv::LINE_AA);
  }
  add_print_grain(image, seed + 13, 0.05f, 0.05f);
  return make_texture(image, texel_m);
}

}  // namespace rankslam::sim::detail
