#include "feature_evaluation.hpp"

#include "rankslam/features/extractor.hpp"

#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <fstream>
#include <numbers>

namespace rankslam::feature_eval {

namespace {

constexpr int kPolygonVertices = 32;
using Polygon = std::vector<cv::Point2d>;

/// Jacobian of x ↦ H·x (dehomogenised) at `p`.
cv::Matx22d jacobian(const cv::Matx33d& h, cv::Point2d p) {
  const double w = h(2, 0) * p.x + h(2, 1) * p.y + h(2, 2);
  const double u = (h(0, 0) * p.x + h(0, 1) * p.y + h(0, 2)) / w;
  const double v = (h(1, 0) * p.x + h(1, 1) * p.y + h(1, 2)) / w;
  return cv::Matx22d((h(0, 0) - u * h(2, 0)) / w, (h(0, 1) - u * h(2, 1)) / w,
                     (h(1, 0) - v * h(2, 0)) / w, (h(1, 1) - v * h(2, 1)) / w);
}

/// Eigenvalues (ascending) of a symmetric 2×2 matrix.
std::array<double, 2> eigenvalues(const cv::Matx22d& q) {
  const double mean = 0.5 * (q(0, 0) + q(1, 1));
  const double diff = 0.5 * (q(0, 0) - q(1, 1));
  const double root = std::sqrt(diff * diff + q(0, 1) * q(0, 1));
  return {mean - root, mean + root};
}

Polygon ellipse_polygon(cv::Point2d c, const cv::Matx22d& q) {
  // Q = V·diag(λ)·Vᵀ; the boundary is c + V·diag(λ^-1/2)·(cos t, sin t).
  const auto lambda = eigenvalues(q);
  const double theta = 0.5 * std::atan2(2.0 * q(0, 1), q(0, 0) - q(1, 1));
  // theta is the direction of the larger eigenvalue's eigenvector: the shorter semi-axis.
  const double a_along = 1.0 / std::sqrt(lambda[1]);
  const double a_across = 1.0 / std::sqrt(lambda[0]);
  const double ct = std::cos(theta);
  const double st = std::sin(theta);
  Polygon poly(kPolygonVertices);
  for (int i = 0; i < kPolygonVertices; ++i) {
    const double t = 2.0 * std::numbers::pi * i / kPolygonVertices;
    const double x = a_along * std::cos(t);
    const double y = a_across * std::sin(t);
    poly[static_cast<std::size_t>(i)] = {c.x + ct * x - st * y, c.y + st * x + ct * y};
  }
  return poly;
}

double polygon_area(const Polygon& p) {
  double sum = 0.0;
  for (std::size_t i = 0, j = p.size() - 1; i < p.size(); j = i++) sum += p[j].x * p[i].y - p[i].x * p[j].y;
  return 0.5 * std::abs(sum);
}

/// Sutherland–Hodgman: `subject` clipped by the convex, counter-clockwise `clip`, into `out`
/// (`scratch` reused: this runs for every candidate pair of dense detectors).
void clip_convex(const Polygon& subject, const Polygon& clip, Polygon& out, Polygon& scratch) {
  out = subject;
  for (std::size_t e = 0; e < clip.size() && !out.empty(); ++e) {
    const cv::Point2d a = clip[e];
    const cv::Point2d b = clip[(e + 1) % clip.size()];
    const auto side = [&](cv::Point2d p) { return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x); };
    scratch.swap(out);
    out.clear();
    for (std::size_t i = 0; i < scratch.size(); ++i) {
      const cv::Point2d p = scratch[i];
      const cv::Point2d q = scratch[(i + 1) % scratch.size()];
      const double sp = side(p);
      const double sq = side(q);
      if (sp >= 0.0) out.push_back(p);
      if ((sp >= 0.0) != (sq >= 0.0)) {
        const double t = sp / (sp - sq);
        out.push_back(p + t * (q - p));
      }
    }
  }
}

/// Area of the intersection of two discs of radii r1, r2 whose centres are d apart.
double lens_area(double r1, double r2, double d) {
  if (d >= r1 + r2) return 0.0;
  const double small = std::min(r1, r2);
  if (d <= std::abs(r1 - r2)) return std::numbers::pi * small * small;
  const double a1 = std::acos(std::clamp((d * d + r1 * r1 - r2 * r2) / (2.0 * d * r1), -1.0, 1.0));
  const double a2 = std::acos(std::clamp((d * d + r2 * r2 - r1 * r1) / (2.0 * d * r2), -1.0, 1.0));
  const double k = (-d + r1 + r2) * (d + r1 - r2) * (d - r1 + r2) * (d + r1 + r2);
  return r1 * r1 * a1 + r2 * r2 * a2 - 0.5 * std::sqrt(std::max(k, 0.0));
}

/// A keypoint's region in image 1: centre, shape, semi-axes and area.
struct Region {
  cv::Point2d c;
  cv::Matx22d q;
  double a_max = 0.0;
  double a_min = 0.0;
  double area = 0.0;
  int index = 0;
};

Region make_region(cv::Point2d c, const cv::Matx22d& q, int index) {
  const auto lambda = eigenvalues(q);
  Region r;
  r.c = c;
  r.q = q;
  r.a_max = 1.0 / std::sqrt(lambda[0]);
  r.a_min = 1.0 / std::sqrt(lambda[1]);
  r.area = std::numbers::pi * r.a_max * r.a_min;
  r.index = index;
  return r;
}

double radius_of(const cv::KeyPoint& kp) { return std::max(0.5 * static_cast<double>(kp.size), 0.5); }

/// The lens of the circumscribed circles bounds the intersection from above: a cheap test that
/// the overlap error can be below `max_error`.
bool may_overlap(const Region& a, const Region& b, double max_error) {
  const double d = std::hypot(a.c.x - b.c.x, a.c.y - b.c.y);
  if (d >= a.a_max + b.a_max) return false;
  const double keep = 1.0 - max_error;
  if (std::min(a.area, b.area) < keep * std::max(a.area, b.area)) return false;
  return lens_area(a.a_max, b.a_max, d) >= keep * std::max(a.area, b.area);
}

double overlap_error(const Region& a, const Region& b) {
  const bool circles = a.a_max - a.a_min <= 1e-9 * a.a_max && b.a_max - b.a_min <= 1e-9 * b.a_max;
  if (circles) {
    // Closed form for two discs: the synthetic similarities keep circles circles.
    const double d = std::hypot(a.c.x - b.c.x, a.c.y - b.c.y);
    const double inter = lens_area(a.a_max, b.a_max, d);
    return 1.0 - inter / (a.area + b.area - inter);
  }
  return ellipse_overlap_error(a.c, a.q, b.c, b.q);
}

}  // namespace

cv::Point2d project(const cv::Matx33d& h, cv::Point2d p) {
  const cv::Vec3d x = h * cv::Vec3d(p.x, p.y, 1.0);
  return {x[0] / x[2], x[1] / x[2]};
}

bool inside(cv::Point2d p, cv::Size size) {
  return p.x >= -0.5 && p.y >= -0.5 && p.x < size.width - 0.5 && p.y < size.height - 0.5;
}

double ellipse_overlap_error(cv::Point2d c1, const cv::Matx22d& q1, cv::Point2d c2, const cv::Matx22d& q2) {
  const Polygon p1 = ellipse_polygon(c1, q1);
  const Polygon p2 = ellipse_polygon(c2, q2);
  const double a1 = polygon_area(p1);
  const double a2 = polygon_area(p2);
  thread_local Polygon both;
  thread_local Polygon scratch;
  clip_convex(p1, p2, both, scratch);
  const double inter = both.size() >= 3 ? polygon_area(both) : 0.0;
  return 1.0 - inter / (a1 + a2 - inter);
}

RepeatabilityResult repeatability(const std::vector<cv::KeyPoint>& kp1, cv::Size size1,
                                  const std::vector<cv::KeyPoint>& kp2, cv::Size size2,
                                  const cv::Matx33d& h1to2, const RepeatabilityOptions& options) {
  const cv::Matx33d h2to1 = h1to2.inv();
  const bool normalised = options.mode == OverlapMode::normalised;
  // Regions of image 2 in image 1, at their own size; normalisation rescales per pair below.
  std::vector<Region> r1;
  std::vector<Region> r2;
  for (std::size_t i = 0; i < kp1.size(); ++i) {
    const cv::Point2d p(kp1[i].pt);
    if (!inside(project(h1to2, p), size2)) continue;
    const double r = radius_of(kp1[i]);
    r1.push_back(make_region(p, cv::Matx22d::eye() * (1.0 / (r * r)), static_cast<int>(i)));
  }
  for (std::size_t j = 0; j < kp2.size(); ++j) {
    const cv::Point2d p(kp2[j].pt);
    const cv::Point2d c = project(h2to1, p);
    if (!inside(c, size1)) continue;
    // x in image 1 lies in the region when |J·(x − c)| ≤ r, J the Jacobian of H1to2 at c.
    const cv::Matx22d jac = jacobian(h1to2, c);
    const double r = radius_of(kp2[j]);
    r2.push_back(make_region(c, jac.t() * jac * (1.0 / (r * r)), static_cast<int>(j)));
  }
  RepeatabilityResult result;
  result.count1 = static_cast<int>(r1.size());
  result.count2 = static_cast<int>(r2.size());
  if (r1.empty() || r2.empty()) return result;

  // Necessary conditions for an overlap error below e (keep = 1 − e): the areas within a factor
  // 1/keep, so r1² ∈ [keep, 1/keep]·(b's semi-axes' product); and the circumscribed circles'
  // lens at least keep·(the larger area). They bound, per region of image 2, the centre
  // distance (`reach`) and the radius of the region-1 candidates.
  const double keep = 1.0 - options.max_overlap_error;
  const double big_r = options.normalised_radius;
  const auto largest_distance = [](double ra, double rb, double needed) {
    double lo = 0.0;
    double hi = ra + rb;
    if (lens_area(ra, rb, 0.0) < needed) return 0.0;
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (lo + hi);
      (lens_area(ra, rb, mid) >= needed ? lo : hi) = mid;
    }
    return hi;
  };
  std::vector<double> reach(r2.size());
  double mean_reach = 0.0;
  for (std::size_t j = 0; j < r2.size(); ++j) {
    const Region& b = r2[j];
    const double g = b.a_max * b.a_min;
    if (normalised) {
      reach[j] = largest_distance(big_r, big_r * std::sqrt(b.a_max / b.a_min / keep), keep * std::numbers::pi * big_r * big_r);
    } else {
      reach[j] = largest_distance(std::sqrt(g / keep), b.a_max, keep * b.area);
    }
    mean_reach += reach[j];
  }
  mean_reach /= static_cast<double>(r2.size());
  const double cell = std::clamp(mean_reach, 2.0, 64.0);
  const int gw = static_cast<int>(std::ceil((size1.width + 1) / cell)) + 1;
  const int gh = static_cast<int>(std::ceil((size1.height + 1) / cell)) + 1;
  std::vector<std::vector<int>> grid(static_cast<std::size_t>(gw) * static_cast<std::size_t>(gh));
  const auto cell_index = [&](double v, int n) { return std::clamp(static_cast<int>((v + 0.5) / cell), 0, n - 1); };
  for (std::size_t i = 0; i < r1.size(); ++i) {
    const int gx = cell_index(r1[i].c.x, gw);
    const int gy = cell_index(r1[i].c.y, gh);
    grid[static_cast<std::size_t>(gy * gw + gx)].push_back(static_cast<int>(i));
  }

  struct Candidate {
    float error;  // float: dense detectors give 10⁷ candidates, all sorted
    int a;
    int b;
  };
  std::vector<Candidate> candidates;
  for (std::size_t j = 0; j < r2.size(); ++j) {
    const Region& b0 = r2[j];
    const double g = b0.a_max * b0.a_min;
    const double reach2 = reach[j] * reach[j];
    for (int gy = cell_index(b0.c.y - reach[j], gh); gy <= cell_index(b0.c.y + reach[j], gh); ++gy) {
      for (int gx = cell_index(b0.c.x - reach[j], gw); gx <= cell_index(b0.c.x + reach[j], gw); ++gx) {
        for (int i : grid[static_cast<std::size_t>(gy * gw + gx)]) {
          const Region& a0 = r1[static_cast<std::size_t>(i)];
          const double dx = a0.c.x - b0.c.x;
          const double dy = a0.c.y - b0.c.y;
          if (dx * dx + dy * dy > reach2) continue;
          const double r1sq = a0.a_max * a0.a_max;
          if (r1sq < keep * g || r1sq * keep > g) continue;
          Region a = a0;
          Region b = b0;
          if (normalised) {
            // The protocol's normalisation: shapes scaled so region 1 has radius R, centres kept.
            const double f = big_r / a0.a_max;
            a.q = cv::Matx22d::eye() * (1.0 / (big_r * big_r));
            a.a_max = a.a_min = big_r;
            a.area = std::numbers::pi * big_r * big_r;
            b.q = b0.q * (1.0 / (f * f));
            b.a_max = b0.a_max * f;
            b.a_min = b0.a_min * f;
            b.area = b0.area * f * f;
          }
          if (!may_overlap(a, b, options.max_overlap_error)) continue;
          const double e = overlap_error(a, b);
          if (e < options.max_overlap_error) candidates.push_back({static_cast<float>(e), i, static_cast<int>(j)});
        }
      }
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return x.error != y.error ? x.error < y.error : (x.a != y.a ? x.a < y.a : x.b < y.b);
  });
  std::vector<char> used1(r1.size(), 0);
  std::vector<char> used2(r2.size(), 0);
  for (const Candidate& c : candidates) {
    if (used1[static_cast<std::size_t>(c.a)] || used2[static_cast<std::size_t>(c.b)]) continue;
    used1[static_cast<std::size_t>(c.a)] = 1;
    used2[static_cast<std::size_t>(c.b)] = 1;
    ++result.repeated;
  }
  result.repeatability = static_cast<double>(result.repeated) / std::min(result.count1, result.count2);
  return result;
}

namespace {

/// Keypoints (and their descriptor rows) whose projection through `h` lies inside `other`.
void common_part(const std::vector<cv::KeyPoint>& kp, const cv::Mat& desc, const cv::Matx33d& h,
                 cv::Size other, std::vector<cv::KeyPoint>& kp_out, cv::Mat& desc_out) {
  kp_out.clear();
  std::vector<int> rows;
  for (std::size_t i = 0; i < kp.size(); ++i) {
    if (!inside(project(h, cv::Point2d(kp[i].pt)), other)) continue;
    kp_out.push_back(kp[i]);
    rows.push_back(static_cast<int>(i));
  }
  desc_out.create(static_cast<int>(rows.size()), desc.cols, desc.type());
  for (std::size_t r = 0; r < rows.size(); ++r) desc.row(rows[r]).copyTo(desc_out.row(static_cast<int>(r)));
}

/// Nearest neighbour in `train` of every row of `query` (−1 where the index found none).
std::vector<int> nearest(const cv::Mat& query, const cv::Mat& train, int norm_type, bool exact) {
  std::vector<int> out(static_cast<std::size_t>(query.rows), -1);
  std::vector<cv::DMatch> m;
  if (exact) {
    cv::BFMatcher(norm_type, false).match(query, train, m);
  } else if (query.depth() == CV_32F) {
    cv::FlannBasedMatcher(cv::makePtr<cv::flann::KDTreeIndexParams>(4), cv::makePtr<cv::flann::SearchParams>(64))
        .match(query, train, m);
  } else {
    cv::FlannBasedMatcher(cv::makePtr<cv::flann::LshIndexParams>(12, 20, 2), cv::makePtr<cv::flann::SearchParams>(64))
        .match(query, train, m);
  }
  for (const cv::DMatch& d : m)
    if (d.queryIdx >= 0 && d.trainIdx >= 0) out[static_cast<std::size_t>(d.queryIdx)] = d.trainIdx;
  return out;
}

}  // namespace

MatchingResult match_inliers(const std::vector<cv::KeyPoint>& kp1, const cv::Mat& desc1, cv::Size size1,
                             const std::vector<cv::KeyPoint>& kp2, const cv::Mat& desc2, cv::Size size2,
                             const cv::Matx33d& h1to2, int norm_type, double max_pixel_error,
                             double exact_pairs_limit) {
  MatchingResult result;
  if (desc1.empty() || desc2.empty()) return result;
  std::vector<cv::KeyPoint> c1;
  std::vector<cv::KeyPoint> c2;
  cv::Mat d1;
  cv::Mat d2;
  common_part(kp1, desc1, h1to2, size2, c1, d1);
  common_part(kp2, desc2, h1to2.inv(), size1, c2, d2);
  if (c1.empty() || c2.empty()) return result;
  const bool exact = static_cast<double>(c1.size()) * static_cast<double>(c2.size()) <= exact_pairs_limit;
  const std::vector<int> to2 = nearest(d1, d2, norm_type, exact);
  const std::vector<int> to1 = nearest(d2, d1, norm_type, exact);
  for (std::size_t i = 0; i < to2.size(); ++i) {
    const int j = to2[i];
    if (j < 0 || to1[static_cast<std::size_t>(j)] != static_cast<int>(i)) continue;
    ++result.matches;
    const cv::Point2d p = project(h1to2, cv::Point2d(c1[i].pt));
    const cv::Point2d q(c2[static_cast<std::size_t>(j)].pt);
    if (std::hypot(p.x - q.x, p.y - q.y) <= max_pixel_error) ++result.inliers;
  }
  if (result.matches > 0) result.inlier_ratio = static_cast<double>(result.inliers) / result.matches;
  return result;
}

Transformed rotate(const cv::Mat& image, double degrees) {
  Transformed t;
  t.family = "rotation";
  t.label = "rotation " + std::to_string(static_cast<int>(std::lround(degrees))) + "°";
  const cv::Point2f centre(0.5f * static_cast<float>(image.cols - 1), 0.5f * static_cast<float>(image.rows - 1));
  const cv::Mat m = cv::getRotationMatrix2D(centre, degrees, 1.0);
  cv::warpAffine(image, t.image, m, image.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar::all(0));
  for (int r = 0; r < 2; ++r)
    for (int c = 0; c < 3; ++c) t.h(r, c) = m.at<double>(r, c);
  return t;
}

Transformed scale(const cv::Mat& image, double factor) {
  Transformed t;
  t.family = "scale";
  char label[32];
  std::snprintf(label, sizeof label, "scale %.2g", factor);
  t.label = label;
  const cv::Size size(static_cast<int>(std::lround(image.cols * factor)),
                      static_cast<int>(std::lround(image.rows * factor)));
  cv::resize(image, t.image, size, 0, 0, factor < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
  // cv::resize maps pixel centres: x' + 0.5 = (x + 0.5)·(w'/w), per axis.
  const double fx = static_cast<double>(size.width) / image.cols;
  const double fy = static_cast<double>(size.height) / image.rows;
  t.h = cv::Matx33d(fx, 0, 0.5 * (fx - 1.0), 0, fy, 0.5 * (fy - 1.0), 0, 0, 1);
  return t;
}

Transformed blur(const cv::Mat& image, double sigma) {
  Transformed t;
  t.family = "blur";
  char label[32];
  std::snprintf(label, sizeof label, "blur σ %.3g", sigma);
  t.label = label;
  cv::GaussianBlur(image, t.image, cv::Size(), sigma, sigma, cv::BORDER_REFLECT_101);
  return t;
}

Transformed jpeg(const cv::Mat& image, int quality) {
  Transformed t;
  t.family = "jpeg";
  t.label = "JPEG q " + std::to_string(quality);
  std::vector<uchar> bytes;
  cv::imencode(".jpg", image, bytes, {cv::IMWRITE_JPEG_QUALITY, quality});
  t.image = cv::imdecode(bytes, image.channels() == 1 ? cv::IMREAD_GRAYSCALE : cv::IMREAD_COLOR);
  return t;
}

Transformed brightness(const cv::Mat& image, double factor) {
  Transformed t;
  t.family = "brightness";
  char label[32];
  std::snprintf(label, sizeof label, "brightness ×%.2g", factor);
  t.label = label;
  image.convertTo(t.image, image.type(), factor, 0.0);
  return t;
}

std::vector<Transformed> standard_transformations(const cv::Mat& image) {
  std::vector<Transformed> out;
  // Two levels per family at most (rotation three): ROS2D's 10⁵ features per image make a row
  // cost about half a minute.
  for (double deg : {30.0, 90.0, 180.0}) out.push_back(rotate(image, deg));
  for (double s : {0.5, 2.0}) out.push_back(scale(image, s));
  out.push_back(blur(image, 2.0));
  out.push_back(jpeg(image, 20));
  for (double f : {0.5, 1.6}) out.push_back(brightness(image, f));
  return out;
}

Peer ros2d_peer(int max_features) {
  features::ExtractorOptions options;
  options.max_features = max_features;
  auto ros2d = std::make_shared<features::FeatureExtractor>(options);
  return {max_features > 0 ? "ROS2D " + std::to_string(max_features) : "ROS2D", ros2d->norm_type(),
          [ros2d](const cv::Mat& g, std::vector<cv::KeyPoint>& k, cv::Mat& d) { ros2d->extract(g, k, d); },
          [ros2d](const cv::Mat& g, std::vector<cv::KeyPoint>& k) { ros2d->detect(g, k); }};
}

std::vector<Peer> make_peers(int orb_features) {
  std::vector<Peer> peers;
  peers.push_back(ros2d_peer());
  const auto opencv = [&peers](std::string name, int norm, cv::Ptr<cv::Feature2D> f) {
    peers.push_back({std::move(name), norm,
                     [f](const cv::Mat& g, std::vector<cv::KeyPoint>& k, cv::Mat& d) {
                       f->detectAndCompute(g, cv::noArray(), k, d);
                     },
                     [f](const cv::Mat& g, std::vector<cv::KeyPoint>& k) { f->detect(g, k); }});
  };
  opencv("SIFT", cv::NORM_L2, cv::SIFT::create());
  // ORB's default 500 would cap its count; the comparison is about counts too.
  opencv("ORB", cv::NORM_HAMMING, cv::ORB::create(orb_features));
  opencv("BRISK", cv::NORM_HAMMING, cv::BRISK::create());
  opencv("AKAZE", cv::NORM_HAMMING, cv::AKAZE::create());
  {
    cv::Ptr<cv::FastFeatureDetector> fast = cv::FastFeatureDetector::create(20, true);
    cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
    peers.push_back({"FAST+SIFT", cv::NORM_L2,
                     [fast, sift](const cv::Mat& g, std::vector<cv::KeyPoint>& k, cv::Mat& d) {
                       fast->detect(g, k);
                       sift->compute(g, k, d);
                     },
                     [fast](const cv::Mat& g, std::vector<cv::KeyPoint>& k) { fast->detect(g, k); }});
  }
  return peers;
}

PairScore evaluate_pair(Peer& peer, const cv::Mat& grey1, const cv::Mat& grey2, const cv::Matx33d& h1to2,
                        bool matching) {
  PairScore s;
  std::vector<cv::KeyPoint> k1;
  std::vector<cv::KeyPoint> k2;
  cv::Mat d1;
  cv::Mat d2;
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  if (matching) {
    peer.extract(grey1, k1, d1);
    peer.extract(grey2, k2, d2);
  } else {
    peer.detect(grey1, k1);
    peer.detect(grey2, k2);
  }
  const auto t2 = clock::now();
  s.extract_ms = 0.5 * std::chrono::duration<double, std::milli>(t2 - t0).count();
  s.count = static_cast<int>((k1.size() + k2.size()) / 2);
  s.rep = repeatability(k1, grey1.size(), k2, grey2.size(), h1to2);
  RepeatabilityOptions plain;
  plain.mode = OverlapMode::plain;
  s.rep_plain = repeatability(k1, grey1.size(), k2, grey2.size(), h1to2, plain);
  if (matching) s.matching = match_inliers(k1, d1, grey1.size(), k2, d2, grey2.size(), h1to2, peer.norm_type);
  return s;
}

bool read_homography(const std::string& path, cv::Matx33d& h) {
  std::ifstream in(path);
  for (int i = 0; i < 9; ++i)
    if (!(in >> h.val[i])) return false;
  return true;
}

}  // namespace rankslam::feature_eval
