#pragma once

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace rankslam::test {

/// Writes a small recording in the TUM layout into a fresh temporary directory named `name`.
inline std::filesystem::path write_small_recording(const std::string& name, int frames, bool with_associations,
                                                   bool with_calibration) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / name;
  fs::remove_all(root);
  fs::create_directories(root / "rgb");
  fs::create_directories(root / "depth");
  std::ofstream rgb_list(root / "rgb.txt");
  std::ofstream depth_list(root / "depth.txt");
  std::ofstream associations;
  if (with_associations) associations.open(root / "associations.txt");
  rgb_list << "# timestamp filename\n";
  depth_list << "# timestamp filename\n";
  for (int i = 0; i < frames; ++i) {
    char rgb_name[64];
    char depth_name[64];
    const double rgb_stamp = 100.0 + i / 30.0;
    const double depth_stamp = rgb_stamp + 0.004;
    std::snprintf(rgb_name, sizeof rgb_name, "rgb/%.6f.png", rgb_stamp);
    std::snprintf(depth_name, sizeof depth_name, "depth/%.6f.png", depth_stamp);
    cv::Mat rgb(48, 64, CV_8UC3, cv::Scalar(i, 2 * i, 3 * i));
    cv::Mat depth(48, 64, CV_16UC1, cv::Scalar(5000 + i));
    cv::imwrite((root / rgb_name).string(), rgb);
    cv::imwrite((root / depth_name).string(), depth);
    char line[160];
    std::snprintf(line, sizeof line, "%.6f %s\n", rgb_stamp, rgb_name);
    rgb_list << line;
    std::snprintf(line, sizeof line, "%.6f %s\n", depth_stamp, depth_name);
    depth_list << line;
    if (with_associations) {
      std::snprintf(line, sizeof line, "%.6f %s %.6f %s\n", rgb_stamp, rgb_name, depth_stamp, depth_name);
      associations << line;
    }
  }
  if (with_calibration) {
    std::ofstream calibration(root / "calibration.yaml");
    calibration << "depth_scale: 5000.0\n"
                   "cameras:\n"
                   "  rgb:\n"
                   "    model: pinhole\n"
                   "    width: 64\n"
                   "    height: 48\n"
                   "    intrinsics: [50.0, 50.0, 32.0, 24.0]\n"
                   "    distortion: [0, 0, 0, 0, 0]\n"
                   "    T_base_cam:\n"
                   "      translation: [0.1, 0.0, 0.5]\n"
                   "      rotation_xyzw: [-0.5, 0.5, -0.5, 0.5]\n";
  }
  return root;
}

/// Adds wide-angle images (32x24, grey value 10·k) at `stamps` to a small recording, the k-th
/// listed in fisheye.txt as fisheye/k.png, and the fisheye camera to its calibration.
inline void add_wide_images(const std::filesystem::path& root, const std::vector<double>& stamps) {
  namespace fs = std::filesystem;
  fs::create_directories(root / "fisheye");
  std::ofstream list(root / "fisheye.txt");
  for (std::size_t k = 0; k < stamps.size(); ++k) {
    const std::string name = "fisheye/" + std::to_string(k) + ".png";
    cv::imwrite((root / name).string(), cv::Mat(24, 32, CV_8UC3, cv::Scalar::all(10.0 * static_cast<double>(k))));
    char line[64];
    std::snprintf(line, sizeof line, "%.6f %s\n", stamps[k], name.c_str());
    list << line;
  }
  std::ofstream calibration(root / "calibration.yaml", std::ios::app);
  calibration << "  fisheye:\n"
                 "    model: fisheye\n"
                 "    width: 32\n"
                 "    height: 24\n"
                 "    intrinsics: [10.0, 10.0, 16.0, 12.0]\n"
                 "    distortion: [0, 0, 0, 0]\n";
}

}  // namespace rankslam::test
