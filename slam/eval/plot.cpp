#include "rankslam/eval/plot.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "rankslam/eval/metrics.hpp"
#include "rankslam/hal/atomic_file.hpp"

namespace rankslam::eval {
namespace {

constexpr int kMinSidePx = 200;
constexpr int kMaxSidePx = 8000;
constexpr int kMarginLeftPx = 64;
constexpr int kMarginRightPx = 20;
constexpr int kMarginTopPx = 72;  // title and legend live above the plot, never over a curve
constexpr int kMarginBottomPx = 44;
constexpr int kCurveThicknessPx = 2;
constexpr int kSubPixelBits = 4;  // polylines are drawn with 1/16 px precision
constexpr double kMinExtent_m = 0.1;
constexpr double kPadding = 1.08;  // the curves keep a small gap to the frame
constexpr int kTargetGridLines = 8;
const cv::Scalar kBackground{255, 255, 255};
const cv::Scalar kGridBgr{228, 228, 228};
const cv::Scalar kOriginGridBgr{190, 190, 190};
const cv::Scalar kFrameBgr{150, 150, 150};
const cv::Scalar kTextBgr{60, 60, 60};
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kLabelScale = 0.4;
constexpr double kLegendScale = 0.5;

std::vector<Eigen::Vector3d> finite_positions_by_stamp(
    const Trajectory& trajectory, double from_s = -std::numeric_limits<double>::infinity(),
    double to_s = std::numeric_limits<double>::infinity()) {
  std::vector<const StampedPose*> sorted;
  sorted.reserve(trajectory.size());
  for (const StampedPose& pose : trajectory) {
    if (std::isfinite(pose.stamp_s) && pose.stamp_s >= from_s && pose.stamp_s <= to_s &&
        pose.T_world_cam.translation().allFinite()) {
      sorted.push_back(&pose);
    }
  }
  std::stable_sort(sorted.begin(), sorted.end(), [](const StampedPose* a, const StampedPose* b) {
    return a->stamp_s < b->stamp_s;
  });
  std::vector<Eigen::Vector3d> positions;
  positions.reserve(sorted.size());
  for (const StampedPose* pose : sorted) positions.push_back(pose->T_world_cam.translation());
  return positions;
}

/// Eigenvectors have no sign; fix one so the same data always gives the same picture.
Eigen::Vector3d with_largest_component_positive(const Eigen::Vector3d& axis) {
  Eigen::Index largest = 0;
  axis.cwiseAbs().maxCoeff(&largest);
  return axis(largest) < 0.0 ? Eigen::Vector3d(-axis) : axis;
}

/// Plane of the two principal axes of largest variance: u (largest), v, and the normal n with
/// (u, v, n) right-handed, so the picture is seen from +n and is never mirrored.
struct ViewPlane {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v = Eigen::Vector3d::UnitY();
};

ViewPlane principal_plane(std::span<const Eigen::Vector3d> positions) {
  ViewPlane plane;
  if (positions.empty()) return plane;
  for (const Eigen::Vector3d& p : positions) plane.origin += p;
  plane.origin /= static_cast<double>(positions.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : positions) {
    const Eigen::Vector3d d = p - plane.origin;
    covariance += d * d.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  if (solver.info() != Eigen::Success) return plane;
  // Eigenvalues ascend: column 2 has the largest variance, column 0 is the plane's normal.
  plane.u = with_largest_component_positive(solver.eigenvectors().col(2));
  const Eigen::Vector3d normal = with_largest_component_positive(solver.eigenvectors().col(0));
  plane.v = normal.cross(plane.u).normalized();
  return plane;
}

/// Smallest of 1, 2, 5 x 10^k that is at least `raw`.
double nice_step(double raw) {
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double factor : {1.0, 2.0, 5.0, 10.0}) {
    if (factor * decade >= raw) return factor * decade;
  }
  return 10.0 * decade;
}

std::string metres_text(double value_m, int decimals) {
  std::array<char, 48> buffer{};
  if (std::abs(value_m) < 0.5 * std::pow(10.0, -decimals)) value_m = 0.0;  // no "-0.0"
  std::snprintf(buffer.data(), buffer.size(), "%.*f", decimals, value_m);
  return buffer.data();
}

struct Mapping {
  cv::Rect plot;
  double centre_u_m = 0.0;
  double centre_v_m = 0.0;
  double metres_per_px = 1.0;

  [[nodiscard]] cv::Point2d to_pixel(const Eigen::Vector2d& uv) const {
    return {plot.x + 0.5 * plot.width + (uv.x() - centre_u_m) / metres_per_px,
            plot.y + 0.5 * plot.height - (uv.y() - centre_v_m) / metres_per_px};
  }
};

void draw_grid(cv::Mat& image, const Mapping& mapping) {
  const cv::Rect& plot = mapping.plot;
  const double half_u_m = 0.5 * plot.width * mapping.metres_per_px;
  const double half_v_m = 0.5 * plot.height * mapping.metres_per_px;
  const double step_m = nice_step(2.0 * std::max(half_u_m, half_v_m) / kTargetGridLines);
  const int decimals = std::clamp(static_cast<int>(-std::floor(std::log10(step_m))), 0, 6);

  const double u_min = mapping.centre_u_m - half_u_m;
  const double u_max = mapping.centre_u_m + half_u_m;
  for (double k = std::ceil(u_min / step_m); k * step_m <= u_max; k += 1.0) {
    const double u_m = k * step_m;
    const int x = static_cast<int>(std::lround(mapping.to_pixel({u_m, 0.0}).x));
    cv::line(image, {x, plot.y}, {x, plot.y + plot.height - 1},
             k == 0.0 ? kOriginGridBgr : kGridBgr, 1);
    const std::string label = metres_text(u_m, decimals);
    int baseline = 0;
    const cv::Size size = cv::getTextSize(label, kFont, kLabelScale, 1, &baseline);
    cv::putText(image, label, {x - size.width / 2, plot.y + plot.height + 16}, kFont, kLabelScale,
                kTextBgr, 1, cv::LINE_AA);
  }
  const double v_min = mapping.centre_v_m - half_v_m;
  const double v_max = mapping.centre_v_m + half_v_m;
  for (double k = std::ceil(v_min / step_m); k * step_m <= v_max; k += 1.0) {
    const double v_m = k * step_m;
    const int y = static_cast<int>(std::lround(mapping.to_pixel({0.0, v_m}).y));
    cv::line(image, {plot.x, y}, {plot.x + plot.width - 1, y}, k == 0.0 ? kOriginGridBgr : kGridBgr,
             1);
    const std::string label = metres_text(v_m, decimals);
    int baseline = 0;
    const cv::Size size = cv::getTextSize(label, kFont, kLabelScale, 1, &baseline);
    cv::putText(image, label, {plot.x - size.width - 6, y + size.height / 2}, kFont, kLabelScale,
                kTextBgr, 1, cv::LINE_AA);
  }
  cv::rectangle(image, plot, kFrameBgr, 1);
  cv::putText(image, "metres from the mean position, on the plane of the two principal axes",
              {plot.x, plot.y + plot.height + 36}, kFont, kLabelScale, kTextBgr, 1, cv::LINE_AA);
}

void draw_curve(cv::Mat& image, const Mapping& mapping, std::span<const Eigen::Vector2d> uv,
                const cv::Scalar& bgr) {
  if (uv.empty()) return;
  constexpr double kScale = 1 << kSubPixelBits;
  std::vector<cv::Point> points;
  points.reserve(uv.size());
  for (const Eigen::Vector2d& p : uv) {
    const cv::Point2d pixel = mapping.to_pixel(p);
    points.emplace_back(static_cast<int>(std::lround(pixel.x * kScale)),
                        static_cast<int>(std::lround(pixel.y * kScale)));
  }
  cv::polylines(image, points, false, bgr, kCurveThicknessPx, cv::LINE_AA, kSubPixelBits);
  const cv::Point2d start = mapping.to_pixel(uv.front());
  const cv::Point2d end = mapping.to_pixel(uv.back());
  cv::circle(
      image,
      cv::Point(static_cast<int>(std::lround(start.x)), static_cast<int>(std::lround(start.y))), 6,
      bgr, cv::FILLED, cv::LINE_AA);
  cv::drawMarker(
      image, cv::Point(static_cast<int>(std::lround(end.x)), static_cast<int>(std::lround(end.y))),
      bgr, cv::MARKER_TILTED_CROSS, 14, 2, cv::LINE_AA);
}

void draw_legend(cv::Mat& image, const TopViewOptions& options, bool has_truth, bool aligned) {
  if (!options.title.empty()) {
    cv::putText(image, options.title, {kMarginLeftPx, 24}, kFont, 0.6, kTextBgr, 1, cv::LINE_AA);
  }
  int x = kMarginLeftPx;
  const int y = 54;
  auto add_entry = [&](const std::string& text, const cv::Scalar* swatch_bgr) {
    if (swatch_bgr != nullptr) {
      cv::line(image, {x, y - 5}, {x + 28, y - 5}, *swatch_bgr, 3, cv::LINE_AA);
      x += 36;
    }
    int baseline = 0;
    const cv::Size size = cv::getTextSize(text, kFont, kLegendScale, 1, &baseline);
    cv::putText(image, text, {x, y}, kFont, kLegendScale, kTextBgr, 1, cv::LINE_AA);
    x += size.width + 22;
  };
  if (has_truth) add_entry("ground truth", &options.ground_truth_bgr);
  add_entry(aligned ? "estimate (aligned)" : "estimate", &options.estimate_bgr);
  if (options.ate_rmse_m) {
    std::array<char, 64> text{};
    std::snprintf(text.data(), text.size(), "ATE RMSE %.4f m", *options.ate_rmse_m);
    add_entry(text.data(), nullptr);
  }
  add_entry("o start  x end", nullptr);
}

}  // namespace

cv::Mat render_top_view(const Trajectory& estimate, const Trajectory* ground_truth_or_null,
                        const TopViewOptions& options) {
  const int width_px = std::clamp(options.width_px, kMinSidePx, kMaxSidePx);
  const int height_px = std::clamp(options.height_px, kMinSidePx, kMaxSidePx);
  cv::Mat image(height_px, width_px, CV_8UC3, kBackground);

  const bool has_truth = ground_truth_or_null != nullptr && !ground_truth_or_null->empty();
  const Trajectory* shown_estimate = &estimate;
  Result<AteResult> ate = Result<AteResult>::failure("not aligned");
  if (has_truth && options.align_estimate) {
    AteOptions ate_options;
    ate_options.max_difference_s = options.max_difference_s;
    ate = compute_ate(*ground_truth_or_null, estimate, ate_options);
    if (ate.ok()) shown_estimate = &ate.value().aligned_estimate;
  }
  // The ground truth over the estimate's span only: a run over part of a recording is drawn
  // against that part.
  double from_s = std::numeric_limits<double>::infinity();
  double to_s = -from_s;
  for (const StampedPose& pose : estimate) {
    if (!std::isfinite(pose.stamp_s)) continue;
    from_s = std::min(from_s, pose.stamp_s);
    to_s = std::max(to_s, pose.stamp_s);
  }
  if (from_s > to_s) {
    from_s = -std::numeric_limits<double>::infinity();
    to_s = std::numeric_limits<double>::infinity();
  }
  const double slack_s = std::max(options.max_difference_s, 0.0);
  const std::vector<Eigen::Vector3d> truth_xyz =
      has_truth ? finite_positions_by_stamp(*ground_truth_or_null, from_s - slack_s, to_s + slack_s)
                : std::vector<Eigen::Vector3d>{};
  const std::vector<Eigen::Vector3d> estimate_xyz = finite_positions_by_stamp(*shown_estimate);

  if (options.show_legend) draw_legend(image, options, has_truth, ate.ok());
  const cv::Rect plot(kMarginLeftPx, kMarginTopPx, width_px - kMarginLeftPx - kMarginRightPx,
                      height_px - kMarginTopPx - kMarginBottomPx);
  if (truth_xyz.empty() && estimate_xyz.empty()) {
    cv::rectangle(image, plot, kFrameBgr, 1);
    cv::putText(image, "no poses", {plot.x + plot.width / 2 - 40, plot.y + plot.height / 2}, kFont,
                0.7, kTextBgr, 1, cv::LINE_AA);
    return image;
  }

  const ViewPlane plane = principal_plane(truth_xyz.empty() ? estimate_xyz : truth_xyz);
  auto project = [&plane](const std::vector<Eigen::Vector3d>& xyz) {
    std::vector<Eigen::Vector2d> uv;
    uv.reserve(xyz.size());
    for (const Eigen::Vector3d& p : xyz) {
      const Eigen::Vector3d d = p - plane.origin;
      uv.emplace_back(plane.u.dot(d), plane.v.dot(d));
    }
    return uv;
  };
  const std::vector<Eigen::Vector2d> truth_uv = project(truth_xyz);
  const std::vector<Eigen::Vector2d> estimate_uv = project(estimate_xyz);

  Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d high = -low;
  for (const auto* curve : {&truth_uv, &estimate_uv}) {
    for (const Eigen::Vector2d& p : *curve) {
      low = low.cwiseMin(p);
      high = high.cwiseMax(p);
    }
  }
  Mapping mapping;
  mapping.plot = plot;
  mapping.centre_u_m = 0.5 * (low.x() + high.x());
  mapping.centre_v_m = 0.5 * (low.y() + high.y());
  // One scale for both axes, so circles stay circles.
  const Eigen::Vector2d extent_m = (high - low).cwiseMax(kMinExtent_m);
  mapping.metres_per_px =
      kPadding * std::max(extent_m.x() / plot.width, extent_m.y() / plot.height);

  draw_grid(image, mapping);
  draw_curve(image, mapping, truth_uv, options.ground_truth_bgr);
  draw_curve(image, mapping, estimate_uv, options.estimate_bgr);
  return image;
}

std::vector<uchar> encode_png(const cv::Mat& image) {
  std::vector<uchar> bytes;
  if (image.empty()) return bytes;
  try {
    if (!cv::imencode(".png", image, bytes)) bytes.clear();
  } catch (const cv::Exception&) {
    bytes.clear();
  }
  return bytes;
}

std::string write_png(const std::filesystem::path& path, const cv::Mat& image) {
  const std::vector<uchar> bytes = encode_png(image);
  if (bytes.empty())
    return "cannot encode " + path.string() + " as PNG: empty or unsupported image";
  return hal::write_file_atomically(
      path, std::span<const char>(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace rankslam::eval
