#pragma once

#include <Eigen/Geometry>

#include <array>
#include <optional>
#include <string>

namespace rankslam::hal {

/// Projection model of one camera.
enum class CameraModel {
  kPinhole,  ///< Pinhole with OpenCV radial-tangential distortion k1 k2 p1 p2 k3.
  kFisheye,  ///< OpenCV fisheye (equidistant) model with distortion k1 k2 k3 k4.
};

/// Intrinsics, distortion and mounting of one camera.
struct CameraCalibration {
  CameraModel model = CameraModel::kPinhole;
  int width = 640;
  int height = 480;
  double fx = 0.0;
  double fy = 0.0;
  double cx = 0.0;
  double cy = 0.0;
  /// Pinhole: k1 k2 p1 p2 k3. Fisheye: k1 k2 k3 k4 (fifth unused).
  std::array<double, 5> distortion{};
  /// Maps points from this camera's optical frame into the robot base frame.
  Eigen::Isometry3d T_base_cam = Eigen::Isometry3d::Identity();
  /// Full angle of the lens' image circle (calibration.yaml `field_of_view_deg`); 0 when not
  /// given, and the model's own limit applies.
  double field_of_view_deg = 0.0;
  /// T_base_cam was given (calibration.yaml); otherwise the identity above is a placeholder and
  /// the mounting is unknown.
  bool T_base_cam_given = false;
};

/// Differential-drive wheel geometry and the CAN id its encoder frames use.
struct WheelGeometry {
  double radius_m = 0.05;
  double track_width_m = 0.30;
  int ticks_per_revolution = 4096;
  unsigned can_id = 0x101;
};

/// Everything needed to interpret a recording or a live sensor set.
struct Calibration {
  /// Where the values came from: a calibration.yaml path or a published TUM camera name.
  std::string source;
  /// Raw depth image units per metre (TUM and Kinect: 5000).
  double depth_scale = 5000.0;
  /// a in the depth sensor's axial noise σ_z = a·z² (Kinect v1: 1.425e-3, Khoshelham & Elberink
  /// 2012); every part that weighs depth reads it from here.
  double depth_noise_per_m = 1.425e-3;
  /// Colour camera; depth and IR images are registered to it.
  CameraCalibration rgb;
  std::optional<CameraCalibration> fisheye;
  std::optional<WheelGeometry> wheels;
};

}  // namespace rankslam::hal
