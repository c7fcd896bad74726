#include "rankslam/camera/virtual_views.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace rankslam::camera {

namespace {

/// Angle, in the plane of the optical axis and `axis` (0: x, 1: y), of the wide-angle image's ray
/// through (u, v); the lens' field angle where no ray reaches the pixel.
double edge_angle(const Lens& lens, double u, double v, int axis) {
  const auto ray = lens.unproject(u, v);
  if (!ray) return lens.max_field_angle_rad();
  return std::abs(std::atan2((*ray)(axis), ray->z()));
}

/// Step between neighbouring views' directions along one axis: the outer views reach the wide
/// field's edge, and no view leaves a gap to its neighbour.
double spacing(int views, double view_field, double wide_half_field, double overlap) {
  if (views < 2) return 0.0;
  const double reach = (wide_half_field - view_field / 2.0) / ((views - 1) / 2.0);
  return std::clamp(reach, 0.0, view_field * (1.0 - overlap));
}

}  // namespace

VirtualViews::VirtualViews(const hal::CameraCalibration& wide, const hal::CameraCalibration& view,
                           const VirtualViewOptions& options)
    : lens_(wide) {
  view_camera_ = view;
  view_camera_.model = hal::CameraModel::kPinhole;
  view_camera_.distortion = {};
  const auto& c = view_camera_;
  const double view_h = std::atan(c.cx / c.fx) + std::atan((c.width - 1 - c.cx) / c.fx);
  const double view_v = std::atan(c.cy / c.fy) + std::atan((c.height - 1 - c.cy) / c.fy);
  const double wide_h = (edge_angle(lens_, 0.0, wide.cy, 0) + edge_angle(lens_, wide.width - 1.0, wide.cy, 0)) / 2.0;
  const double wide_v = (edge_angle(lens_, wide.cx, 0.0, 1) + edge_angle(lens_, wide.cx, wide.height - 1.0, 1)) / 2.0;
  const double yaw_step = spacing(options.columns, view_h, wide_h, options.overlap);
  const double pitch_step = spacing(options.rows, view_v, wide_v, options.overlap);

  cv::Mat map_x(c.height, c.width, CV_32FC1);
  cv::Mat map_y(c.height, c.width, CV_32FC1);
  for (int row = 0; row < options.rows; ++row) {
    for (int column = 0; column < options.columns; ++column) {
      const double yaw = (column - (options.columns - 1) / 2.0) * yaw_step;
      const double pitch = (row - (options.rows - 1) / 2.0) * pitch_step;
      View v;
      // Positive yaw looks right (+x), positive pitch looks down (+y).
      v.R_wide_view = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitY()) *
                       Eigen::AngleAxisd(-pitch, Eigen::Vector3d::UnitX()))
                          .toRotationMatrix();
      v.valid.create(c.height, c.width, CV_8UC1);
      for (int y = 0; y < c.height; ++y) {
        for (int x = 0; x < c.width; ++x) {
          const auto pixel = lens_.project(direction(v.R_wide_view, x, y));
          const bool inside = pixel && pixel->x() >= 0.0 && pixel->y() >= 0.0 && pixel->x() <= wide.width - 1.0 &&
                              pixel->y() <= wide.height - 1.0;
          map_x.at<float>(y, x) = inside ? static_cast<float>(pixel->x()) : -1.0F;
          map_y.at<float>(y, x) = inside ? static_cast<float>(pixel->y()) : -1.0F;
          v.valid.at<unsigned char>(y, x) = inside ? 255 : 0;
        }
      }
      cv::convertMaps(map_x, map_y, v.map_xy, v.map_frac, CV_16SC2, false);
      views_.push_back(std::move(v));
    }
  }
}

Eigen::Vector3d VirtualViews::direction(const Eigen::Matrix3d& R_wide_view, double u, double v) const {
  const auto& c = view_camera_;
  return R_wide_view * Eigen::Vector3d((u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0);
}

double VirtualViews::coverage(int index) const {
  const cv::Mat& valid = at(index).valid;
  return static_cast<double>(cv::countNonZero(valid)) / static_cast<double>(valid.total());
}

Eigen::Vector3d VirtualViews::ray(int index, double u, double v) const {
  return direction(at(index).R_wide_view, u, v).normalized();
}

std::optional<Eigen::Vector2d> VirtualViews::wide_pixel(int index, double u, double v) const {
  return lens_.project(direction(at(index).R_wide_view, u, v));
}

std::optional<Eigen::Vector2d> VirtualViews::view_pixel(int index, const Eigen::Vector3d& ray_wide) const {
  const Eigen::Vector3d d = at(index).R_wide_view.transpose() * ray_wide;
  if (!(d.z() > 0.0)) return std::nullopt;
  const auto& c = view_camera_;
  const Eigen::Vector2d pixel(c.fx * d.x() / d.z() + c.cx, c.fy * d.y() / d.z() + c.cy);
  if (pixel.x() < 0.0 || pixel.y() < 0.0 || pixel.x() > c.width - 1.0 || pixel.y() > c.height - 1.0) return std::nullopt;
  return pixel;
}

void VirtualViews::allocate(std::vector<cv::Mat>& views, int type) const {
  views.resize(views_.size());
  for (auto& view : views) view.create(view_camera_.height, view_camera_.width, type);
}

bool VirtualViews::render(const cv::Mat& wide, std::vector<cv::Mat>& views) const {
  const auto& w = lens_.calibration();
  if (wide.cols != w.width || wide.rows != w.height || views.size() != views_.size()) return false;
  for (const auto& view : views) {
    if (view.cols != view_camera_.width || view.rows != view_camera_.height || view.type() != wide.type()) return false;
  }
  for (std::size_t i = 0; i < views_.size(); ++i) {
    cv::remap(wide, views[i], views_[i].map_xy, views_[i].map_frac, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar());
  }
  return true;
}

}  // namespace rankslam::camera
