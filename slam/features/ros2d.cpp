#include "rankslam/features/ros2d.hpp"

#include "rankslam/robust/msse.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <numbers>
#include <span>
#include <stdexcept>
#include <limits>
#include <string>

namespace rankslam::features {

namespace {

constexpr int kOrientationBins = 36;

// Non-negative floats order as their bit patterns do, so three 11-bit radix passes sort them.
void radix_sort(std::vector<float>& values, std::vector<float>& scratch, std::size_t n) {
  constexpr int kBits = 11;
  constexpr std::uint32_t kBuckets = 1U << kBits;
  std::array<std::uint32_t, kBuckets> counts{};
  float* src = values.data();
  float* dst = scratch.data();
  for (int shift = 0; shift < 32; shift += kBits) {
    counts.fill(0);
    for (std::size_t i = 0; i < n; ++i) {
      std::uint32_t bits = 0;
      std::memcpy(&bits, &src[i], sizeof bits);
      ++counts[(bits >> shift) & (kBuckets - 1)];
    }
    std::uint32_t offset = 0;
    for (auto& c : counts) {
      const std::uint32_t here = c;
      c = offset;
      offset += here;
    }
    for (std::size_t i = 0; i < n; ++i) {
      std::uint32_t bits = 0;
      std::memcpy(&bits, &src[i], sizeof bits);
      dst[counts[(bits >> shift) & (kBuckets - 1)]++] = src[i];
    }
    std::swap(src, dst);
  }
  // Three passes: the sorted values are in `scratch`'s buffer.
  if (src != values.data()) std::memcpy(values.data(), src, n * sizeof(float));
}

// Histogram equalisation (OpenCV's mapping), written out so that it allocates nothing.
void equalize(const cv::Mat& grey, cv::Mat& out) {
  std::array<int, 256> hist{};
  for (int y = 0; y < grey.rows; ++y) {
    const std::uint8_t* row = grey.ptr<std::uint8_t>(y);
    for (int x = 0; x < grey.cols; ++x) ++hist[row[x]];
  }
  const int total = grey.rows * grey.cols;
  int first = 0;
  while (first < 255 && hist[static_cast<std::size_t>(first)] == 0) ++first;
  std::array<std::uint8_t, 256> lut{};
  const int first_count = hist[static_cast<std::size_t>(first)];
  if (first_count == total) {
    lut.fill(0);
    lut[static_cast<std::size_t>(first)] = static_cast<std::uint8_t>(first);
  } else {
    const double scale = 255.0 / static_cast<double>(total - first_count);
    int sum = 0;
    for (int i = first + 1; i < 256; ++i) {
      sum += hist[static_cast<std::size_t>(i)];
      lut[static_cast<std::size_t>(i)] = cv::saturate_cast<std::uint8_t>(static_cast<double>(sum) * scale);
    }
  }
  for (int y = 0; y < grey.rows; ++y) {
    const std::uint8_t* src = grey.ptr<std::uint8_t>(y);
    std::uint8_t* dst = out.ptr<std::uint8_t>(y);
    for (int x = 0; x < grey.cols; ++x) dst[x] = lut[src[x]];
  }
}

// The orientation histogram bin of a gradient: its angle in degrees [0, 360) in image axes (y
// down), as cv::KeyPoint, rounded to the nearest of kOrientationBins.
int orientation_bin(float dx, float dy) {
  const int bin = static_cast<int>(cv::fastAtan2(dy, dx) * (kOrientationBins / 360.0F) + 0.5F);
  return bin >= kOrientationBins ? bin - kOrientationBins : bin;
}

// Valid interior of an octave image for a kernel of half-width r: [r, size − r).
struct Interior {
  int x0, x1, y0, y1;
};

}  // namespace

std::string_view Ros2dOptions::validate() const {
  if (octaves < 1 || octaves > 8) return "octaves";
  if (layers < 1 || layers > 8) return "layers";
  if (!(sigma0 > 0.3 && sigma0 <= 10.0)) return "sigma0";
  if (!(min_inlier_fraction > 0.0 && min_inlier_fraction < 1.0)) return "min_inlier_fraction";
  if (!(transition_factor > 0.0 && transition_factor <= 100.0)) return "transition_factor";
  if (border_px < 1 || border_px > 64) return "border_px";
  if (max_features < 0) return "max_features";
  if (!(orientation_peak_ratio > 0.0 && orientation_peak_ratio <= 1.0)) return "orientation_peak_ratio";
  return {};
}

Ros2dDetector::Ros2dDetector(const Ros2dOptions& options) : options_(options) {
  if (const auto field = options_.validate(); !field.empty()) {
    throw std::invalid_argument("Ros2dOptions: " + std::string(field) + " out of range");
  }
  const double k = std::pow(2.0, 1.0 / options_.layers);
  const double sigma_max = options_.sigma0 * std::pow(k, options_.layers - 1);
  // One kernel size for every layer, set by the largest σ (§7.2): ±3σ holds 99.7 % of its weight.
  radius_ = static_cast<int>(std::ceil(3.0 * sigma_max));
  const int ksize = 2 * radius_ + 1;
  kernels_.resize(static_cast<std::size_t>(options_.layers));
  for (int l = 0; l < options_.layers; ++l) {
    const double sigma = options_.sigma0 * std::pow(k, l);
    auto& g = kernels_[static_cast<std::size_t>(l)];
    g.resize(static_cast<std::size_t>(ksize));
    double sum = 0.0;
    for (int i = 0; i < ksize; ++i) {
      const double d = i - (ksize - 1) / 2.0;  // eq. 7.1
      const double v = std::exp(-d * d / (2.0 * sigma * sigma));
      g[static_cast<std::size_t>(i)] = static_cast<float>(v);
      sum += v;
    }
    for (auto& v : g) v = static_cast<float>(static_cast<double>(v) / sum);
    // SIFT's orientation window: radius 3·1.5σ, Gaussian weight of σ_w = 1.5σ (Lowe 2004 §5).
    const double sigma_w = 1.5 * sigma;
    const int radius = static_cast<int>(std::lround(3.0 * sigma_w));
    orientation_radius_.push_back(radius);
    auto& weights = orientation_weights_.emplace_back();
    for (int dy = -radius; dy <= radius; ++dy) {
      for (int dx = -radius; dx <= radius; ++dx) {
        weights.push_back(static_cast<float>(std::exp(-(dx * dx + dy * dy) / (2.0 * sigma_w * sigma_w))));
      }
    }
  }
}

void Ros2dDetector::reserve(cv::Size size) {
  const int octaves = options_.octaves;
  const int layers = options_.layers;
  equalized_.create(size, CV_8UC1);
  octave_images_.resize(static_cast<std::size_t>(2 * octaves));
  residuals_.resize(static_cast<std::size_t>(4 * octaves * layers));
  std::size_t total = 0;
  cv::Size s = size;
  for (int o = 0; o < octaves; ++o) {
    octave_images_[static_cast<std::size_t>(2 * o)].create(s, CV_32F);
    octave_images_[static_cast<std::size_t>(2 * o + 1)].create(s, CV_32F);
    for (int l = 0; l < layers; ++l) {
      // Per layer: residual, Gaussian-weighted mean (for orientation), gradient magnitude and angle.
      for (int t = 0; t < 4; ++t) residuals_[static_cast<std::size_t>(4 * (o * layers + l) + t)].create(s, CV_32F);
      total += static_cast<std::size_t>(s.area());
    }
    s = cv::Size(s.width / 2, s.height / 2);
  }
  blur_a_.create(size, CV_32F);
  blur_b_.create(size, CV_32F);
  tmp_.create(parallel::ThreadTeam::kMaxThreads, size.width + 1, CV_32F);  // a row per thread
  values_.resize(total);
  sort_scratch_.resize(total);
  candidates_.reserve(total);
  gradients_ready_.assign(static_cast<std::size_t>(octaves * layers), 0);
  window_points_.assign(static_cast<std::size_t>(octaves * layers), 0);
}

bool Ros2dDetector::detect(const cv::Mat& grey, std::vector<cv::KeyPoint>& keypoints) {
  keypoints.clear();
  stats_ = {};
  if (grey.empty() || grey.type() != CV_8UC1) return false;
  const int R = radius_;
  const int margin = R + options_.border_px;  // ≥ R + 1: every candidate has its 3×3 computed
  if (grey.cols <= 2 * margin + 2 || grey.rows <= 2 * margin + 2) return false;
  if (grey.cols > equalized_.cols || grey.rows > equalized_.rows || octave_images_.empty()) {
    reserve(cv::Size(std::max(grey.cols, equalized_.cols), std::max(grey.rows, equalized_.rows)));
  }
  // Views of the set-up buffers at this image's size.
  cv::Mat eq = equalized_(cv::Rect(0, 0, grey.cols, grey.rows));
  if (options_.equalize) {
    equalize(grey, eq);
  } else {
    grey.copyTo(eq);
  }
  equalized_view_ = eq;

  const int layers = options_.layers;
  std::size_t n = 0;
  int octaves_used = 0;
  cv::Size s(grey.cols, grey.rows);
  for (int o = 0; o < options_.octaves; ++o) {
    if (s.width <= 2 * margin + 2 || s.height <= 2 * margin + 2) break;
    ++octaves_used;
    cv::Mat I = octave_images_[static_cast<std::size_t>(2 * o)](cv::Rect(0, 0, s.width, s.height));
    cv::Mat I2 = octave_images_[static_cast<std::size_t>(2 * o + 1)](cv::Rect(0, 0, s.width, s.height));
    if (o == 0) {
      for (int y = 0; y < s.height; ++y) {
        const std::uint8_t* src = eq.ptr<std::uint8_t>(y);
        float* dst = I.ptr<float>(y);
        for (int x = 0; x < s.width; ++x) dst[x] = static_cast<float>(src[x]);
      }
    } else {
      // Half resolution: the mean of each 2×2 block of the previous octave.
      const cv::Mat& P = octave_images_[static_cast<std::size_t>(2 * (o - 1))];
      for (int y = 0; y < s.height; ++y) {
        const float* a = P.ptr<float>(2 * y);
        const float* b = P.ptr<float>(2 * y + 1);
        float* dst = I.ptr<float>(y);
        for (int x = 0; x < s.width; ++x) {
          dst[x] = 0.25F * (a[2 * x] + a[2 * x + 1] + b[2 * x] + b[2 * x + 1]);
        }
      }
    }
    for (int y = 0; y < s.height; ++y) {
      const float* src = I.ptr<float>(y);
      float* dst = I2.ptr<float>(y);
      for (int x = 0; x < s.width; ++x) dst[x] = src[x] * src[x];
    }
    const Interior in{R, s.width - R, R, s.height - R};
    cv::Mat HA = blur_a_(cv::Rect(0, 0, s.width, s.height));
    cv::Mat HB = blur_b_(cv::Rect(0, 0, s.width, s.height));
    for (int l = 0; l < layers; ++l) {
      const float* g = kernels_[static_cast<std::size_t>(l)].data() + R;  // g[-R..R]
      // r = Σ w_j (I_c − I_j)² = I_c² − 2·I_c·(G∗I) + G∗I² (Σ w_j = 1): two separable filters of
      // the interior instead of a (2R+1)² window per point.
      for_rows(0, s.height, [&](int y0, int y1, int) {
        for (int y = y0; y < y1; ++y) {
          const float* a = I.ptr<float>(y);
          const float* b = I2.ptr<float>(y);
          float* ha = HA.ptr<float>(y);
          float* hb = HB.ptr<float>(y);
          for (int x = in.x0; x < in.x1; ++x) {
            ha[x] = g[0] * a[x];
            hb[x] = g[0] * b[x];
          }
          for (int k = 1; k <= R; ++k) {
            const float w = g[k];
            for (int x = in.x0; x < in.x1; ++x) {
              ha[x] += w * (a[x - k] + a[x + k]);
              hb[x] += w * (b[x - k] + b[x + k]);
            }
          }
        }
      });
      cv::Mat& res = residuals_[static_cast<std::size_t>(4 * (o * layers + l))];
      cv::Mat& mean = residuals_[static_cast<std::size_t>(4 * (o * layers + l) + 1)];
      for_rows(in.y0, in.y1, [&](int y0, int y1, int thread) {
        float* acc = tmp_.ptr<float>(thread);
        for (int y = y0; y < y1; ++y) {
          float* m = mean.ptr<float>(y);
          const float* ha0 = HA.ptr<float>(y);
          const float* hb0 = HB.ptr<float>(y);
          for (int x = in.x0; x < in.x1; ++x) {
            m[x] = g[0] * ha0[x];
            acc[x] = g[0] * hb0[x];
          }
          for (int k = 1; k <= R; ++k) {
            const float w = g[k];
            const float* ua = HA.ptr<float>(y - k);
            const float* da = HA.ptr<float>(y + k);
            const float* ub = HB.ptr<float>(y - k);
            const float* db = HB.ptr<float>(y + k);
            for (int x = in.x0; x < in.x1; ++x) {
              m[x] += w * (ua[x] + da[x]);
              acc[x] += w * (ub[x] + db[x]);
            }
          }
          const float* c = I.ptr<float>(y);
          const float* c2 = I2.ptr<float>(y);
          float* r = res.ptr<float>(y);
          for (int x = in.x0; x < in.x1; ++x) r[x] = std::max(0.0F, c2[x] - 2.0F * c[x] * m[x] + acc[x]);
        }
      });
      // The residuals that compete: those at least `margin` from the border.
      for (int y = margin; y < s.height - margin; ++y) {
        const float* r = res.ptr<float>(y);
        std::memcpy(values_.data() + n, r + margin, static_cast<std::size_t>(s.width - 2 * margin) * sizeof(float));
        n += static_cast<std::size_t>(s.width - 2 * margin);
      }
      gradients_ready_[static_cast<std::size_t>(o * layers + l)] = 0;
    }
    s = cv::Size(s.width / 2, s.height / 2);
  }
  stats_.residuals = static_cast<std::int64_t>(n);
  if (n < 2) return false;

  // MSSE on all residuals of all layers (§7.3, p = 0): the second group are the features.
  radix_sort(values_, sort_scratch_, n);
  const int k0 = robust::msse_first_order(options_.min_inlier_fraction, static_cast<int>(n), 0, 1);
  const int j = robust::msse_transition(std::span<const float>(values_.data(), n), k0, 0,
                                        options_.transition_factor);
  // Below this the residual is float rounding of I² − 2·I·(G∗I) + G∗I² (≈ 4ε·255²), not texture:
  // a flat image has nothing that stands out.
  constexpr float kRoundingFloor = 0.05F;
  const float threshold =
      j < static_cast<int>(n) ? std::max(values_[static_cast<std::size_t>(j)], kRoundingFloor)
                              : std::numeric_limits<float>::infinity();
  stats_.threshold = static_cast<double>(threshold);
  stats_.second_group = static_cast<std::int64_t>(values_.data() + n -
                                                  std::lower_bound(values_.data(), values_.data() + n, threshold));
  if (stats_.second_group == 0) return true;

  candidates_.clear();
  s = cv::Size(grey.cols, grey.rows);
  const double k = std::pow(2.0, 1.0 / layers);
  for (int o = 0; o < octaves_used; ++o) {
    const float step = static_cast<float>(1 << o);
    for (int l = 0; l < layers; ++l) {
      const cv::Mat& res = residuals_[static_cast<std::size_t>(4 * (o * layers + l))];
      const float size = static_cast<float>(2.0 * options_.sigma0 * std::pow(k, l)) * step;
      for (int y = margin; y < s.height - margin; ++y) {
        const float* up = res.ptr<float>(y - 1);
        const float* r = res.ptr<float>(y);
        const float* dn = res.ptr<float>(y + 1);
        for (int x = margin; x < s.width - margin; ++x) {
          const float v = r[x];
          if (v < threshold) continue;
          // Strict 3×3 peak: the point gets the quadratic peak's sub-pixel offset.
          const bool above_before = v > up[x - 1] && v > up[x] && v > up[x + 1] && v > r[x - 1];
          const bool strict = above_before && v > r[x + 1] && v > dn[x - 1] && v > dn[x] && v > dn[x + 1];
          if (options_.local_peaks_only &&
              !(above_before && v >= r[x + 1] && v >= dn[x - 1] && v >= dn[x] && v >= dn[x + 1])) {
            continue;
          }
          float fx = static_cast<float>(x);
          float fy = static_cast<float>(y);
          if (strict) {
            const float dxx = r[x + 1] - 2.0F * v + r[x - 1];
            const float dyy = dn[x] - 2.0F * v + up[x];
            if (dxx < 0.0F) fx += std::clamp(-0.5F * (r[x + 1] - r[x - 1]) / dxx, -0.5F, 0.5F);
            if (dyy < 0.0F) fy += std::clamp(-0.5F * (dn[x] - up[x]) / dyy, -0.5F, 0.5F);
          }
          // Octave pixel centres to full-resolution pixels (each octave averages 2×2 blocks).
          cv::KeyPoint kp(cv::Point2f((fx + 0.5F) * step - 0.5F, (fy + 0.5F) * step - 0.5F), size, 0.0F, v,
                          o | (l << 8), l);
          candidates_.push_back(kp);
        }
      }
    }
    s = cv::Size(s.width / 2, s.height / 2);
  }
  // Strongest first; ties in a fixed order so that the output never depends on the sort.
  const auto stronger = [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
    if (a.response != b.response) return a.response > b.response;
    if (a.octave != b.octave) return a.octave < b.octave;
    if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
    return a.pt.x < b.pt.x;
  };
  const std::size_t cap = options_.max_features > 0 ? static_cast<std::size_t>(options_.max_features)
                                                     : std::numeric_limits<std::size_t>::max();
  // Each candidate gives at least one keypoint, so only the `cap` strongest can be returned.
  auto last = candidates_.end();
  if (cap < candidates_.size()) {
    last = candidates_.begin() + static_cast<std::ptrdiff_t>(cap);
    std::nth_element(candidates_.begin(), last, candidates_.end(), stronger);
  }
  std::sort(candidates_.begin(), last, stronger);
  if (options_.orientation) {
    // A layer's gradient table pays off once its windows cover more points than the layer has.
    std::fill(window_points_.begin(), window_points_.end(), 0);
    for (auto it = candidates_.begin(); it != last; ++it) {
      const int l = it->class_id;
      const int side = 2 * orientation_radius_[static_cast<std::size_t>(l)] + 1;
      window_points_[static_cast<std::size_t>((it->octave & 0xff) * layers + l)] += side * side;
    }
  }
  for (auto it = candidates_.begin(); it != last; ++it) {
    const cv::KeyPoint& c = *it;
    if (keypoints.size() >= cap) break;
    if (!options_.orientation) {
      keypoints.push_back(c);
      continue;
    }
    add_oriented(c, keypoints, cap);
  }
  stats_.features = static_cast<int>(keypoints.size());
  return true;
}

void Ros2dDetector::use_team(parallel::ThreadTeam* team) { team_ = team; }

template <class Body>
void Ros2dDetector::for_rows(int begin, int end, Body&& body) {
  if (end <= begin) return;
  if (parallel::team_size(team_) <= 1) {
    body(begin, end, 0);
    return;
  }
  // Chunks of 16 rows: enough work per chunk, enough chunks to balance two to eight threads.
  team_->for_chunks(end - begin, 16, [&](int b, int e, int thread) { body(begin + b, begin + e, thread); });
}

void Ros2dDetector::prepare_gradients(int octave, int layer) {
  const std::size_t index = static_cast<std::size_t>(octave * options_.layers + layer);
  if (gradients_ready_[index] != 0) return;
  const cv::Mat& mean = residuals_[4 * index + 1];
  cv::Mat& mag = residuals_[4 * index + 2];
  cv::Mat& ang = residuals_[4 * index + 3];
  const int w = equalized_view_.cols >> octave;
  const int h = equalized_view_.rows >> octave;
  const int R = radius_;
  // Gradients of the Gaussian-weighted mean (SIFT's blurred layer) where both neighbours exist.
  for_rows(R + 1, h - R - 1, [&](int y0, int y1, int) {
    for (int y = y0; y < y1; ++y) {
      const float* up = mean.ptr<float>(y - 1);
      const float* m = mean.ptr<float>(y);
      const float* dn = mean.ptr<float>(y + 1);
      float* mg = mag.ptr<float>(y);
      float* an = ang.ptr<float>(y);
      for (int x = R + 1; x < w - R - 1; ++x) {
        const float dx = m[x + 1] - m[x - 1];
        const float dy = dn[x] - up[x];
        mg[x] = std::sqrt(dx * dx + dy * dy);
        an[x] = static_cast<float>(orientation_bin(dx, dy));
      }
    }
  });
  gradients_ready_[index] = 1;
}

void Ros2dDetector::add_oriented(const cv::KeyPoint& c, std::vector<cv::KeyPoint>& out, std::size_t cap) {
  const int o = c.octave & 0xff;
  const int l = c.class_id;
  const std::size_t index = static_cast<std::size_t>(o * options_.layers + l);
  const int w = equalized_view_.cols >> o;
  const int h = equalized_view_.rows >> o;
  const bool table = window_points_[index] > static_cast<std::int64_t>(w) * h;
  if (table) prepare_gradients(o, l);
  const cv::Mat& mean = residuals_[4 * index + 1];
  const cv::Mat& mag = residuals_[4 * index + 2];
  const cv::Mat& ang = residuals_[4 * index + 3];
  const float step = static_cast<float>(1 << o);
  const int cx = static_cast<int>(std::lround((c.pt.x + 0.5F) / step - 0.5F));
  const int cy = static_cast<int>(std::lround((c.pt.y + 0.5F) / step - 0.5F));
  const int radius = orientation_radius_[static_cast<std::size_t>(l)];
  const float* weights = orientation_weights_[static_cast<std::size_t>(l)].data();
  const int lo = radius_ + 1;
  std::array<float, kOrientationBins + 4> raw{};
  float* hist = raw.data() + 2;
  for (int dy = -radius; dy <= radius; ++dy) {
    const int y = cy + dy;
    if (y < lo || y >= h - lo) continue;
    const float* mg = mag.ptr<float>(y);
    const float* an = ang.ptr<float>(y);
    const float* wrow = weights + (dy + radius) * (2 * radius + 1) + radius;
    const int x0 = std::max(-radius, lo - cx);
    const int x1 = std::min(radius, w - lo - 1 - cx);
    if (table) {
      for (int dx = x0; dx <= x1; ++dx) hist[static_cast<int>(an[cx + dx])] += wrow[dx] * mg[cx + dx];
      continue;
    }
    const float* up = mean.ptr<float>(y - 1);
    const float* m = mean.ptr<float>(y);
    const float* dn = mean.ptr<float>(y + 1);
    for (int dx = x0; dx <= x1; ++dx) {
      const int x = cx + dx;
      const float gx = m[x + 1] - m[x - 1];
      const float gy = dn[x] - up[x];
      hist[orientation_bin(gx, gy)] += wrow[dx] * std::sqrt(gx * gx + gy * gy);
    }
  }
  // SIFT's [1 4 6 4 1]/16 smoothing of the circular histogram.
  raw[0] = hist[kOrientationBins - 2];
  raw[1] = hist[kOrientationBins - 1];
  hist[kOrientationBins] = hist[0];
  hist[kOrientationBins + 1] = hist[1];
  std::array<float, kOrientationBins> smooth{};
  for (int i = 0; i < kOrientationBins; ++i) {
    smooth[static_cast<std::size_t>(i)] = (hist[i - 2] + hist[i + 2]) * (1.0F / 16.0F) +
                                          (hist[i - 1] + hist[i + 1]) * (4.0F / 16.0F) + hist[i] * (6.0F / 16.0F);
  }
  const float highest = *std::max_element(smooth.begin(), smooth.end());
  if (!(highest > 0.0F)) {
    out.push_back(c);  // no gradient at all: upright
    return;
  }
  const float floor_value = static_cast<float>(options_.orientation_peak_ratio) * highest;
  for (int i = 0; i < kOrientationBins && out.size() < cap; ++i) {
    const float left = smooth[static_cast<std::size_t>((i + kOrientationBins - 1) % kOrientationBins)];
    const float right = smooth[static_cast<std::size_t>((i + 1) % kOrientationBins)];
    const float v = smooth[static_cast<std::size_t>(i)];
    if (!(v > left && v > right && v >= floor_value)) continue;
    // Parabolic interpolation of the peak between its neighbours.
    float bin = static_cast<float>(i) + 0.5F * (left - right) / (left - 2.0F * v + right);
    if (bin < 0.0F) bin += kOrientationBins;
    if (bin >= kOrientationBins) bin -= kOrientationBins;
    cv::KeyPoint kp = c;
    kp.angle = bin * (360.0F / kOrientationBins);
    if (kp.angle >= 360.0F) kp.angle -= 360.0F;
    out.push_back(kp);
  }
}

}  // namespace rankslam::features
