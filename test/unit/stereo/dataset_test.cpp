// The EuRoC and KITTI readers on small generated layouts, good and bad.
#include "rankslam/stereo/dataset.hpp"
#include "rankslam/stereo/rectifier.hpp"

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

namespace {

namespace fs = std::filesystem;
using namespace rankslam::stereo;

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() /
            ("rankslam_stereo_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  [[nodiscard]] const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

void write(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

void write_png(const fs::path& path, int width = 64, int height = 48) {
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat(height, width, CV_8UC1, cv::Scalar(100))));
}

std::string sensor_yaml(double body_x) {
  return "%YAML:1.0\nsensor_type: camera\nT_BS:\n  cols: 4\n  rows: 4\n  data: [1.0, 0.0, 0.0, " + std::to_string(body_x) +
         ",\n         0.0, 1.0, 0.0, 0.0,\n         0.0, 0.0, 1.0, 0.0,\n         0.0, 0.0, 0.0, 1.0]\n"
         "rate_hz: 20\nresolution: [64, 48]\ncamera_model: pinhole\nintrinsics: [50.0, 51.0, 32.0, 24.0]\n"
         "distortion_model: radial-tangential\ndistortion_coefficients: [-0.1, 0.01, 0.001, 0.0002]\n";
}

/// cam0 has stamps 100, 200, 300; cam1 lacks 200 (the reader pairs by identical stamp).
void write_euroc(const fs::path& dir) {
  write(dir / "mav0/cam0/sensor.yaml", sensor_yaml(0.0));
  write(dir / "mav0/cam1/sensor.yaml", sensor_yaml(0.11));
  write(dir / "mav0/cam0/data.csv", "#timestamp [ns],filename\n100,100.png\n200,200.png\n300,300.png\n");
  write(dir / "mav0/cam1/data.csv", "#timestamp [ns],filename\n100,100.png\n300,300.png\n");
  for (const char* name : {"100.png", "200.png", "300.png"}) write_png(dir / "mav0/cam0/data" / name);
  for (const char* name : {"100.png", "300.png"}) write_png(dir / "mav0/cam1/data" / name);
  write(dir / "groundtruth_cam0_euroc.txt",
        "#timestamp [ns],p x,p y,p z,q w,q x,q y,q z\n100.0000000000,1,2,3,1,0,0,0\n300.0000000000,1.5,2,3,0,0,0,1\n");
}

TEST(EurocReader, PairsByStampAndReadsCalibrationAndGroundTruth) {
  TempDir dir;
  write_euroc(dir.path());
  const auto dataset = read_stereo_dataset(dir.path());
  ASSERT_TRUE(dataset.ok()) << dataset.error();
  const StereoDataset& d = dataset.value();
  EXPECT_EQ(d.layout, DatasetLayout::euroc);
  ASSERT_EQ(d.frames.size(), 2u);
  EXPECT_EQ(d.unpaired_frames, 1);
  EXPECT_EQ(d.frames[1].stamp_ns, 300);
  EXPECT_EQ(d.frames[1].right.filename(), "300.png");
  EXPECT_DOUBLE_EQ(d.calibration.left.fv, 51.0);
  EXPECT_DOUBLE_EQ(d.calibration.right.radtan[3], 0.0002);
  EXPECT_EQ(d.calibration.left.size, cv::Size(64, 48));
  // cam1 sits 0.11 m along the body's x = the cameras' x here: left points are at x − 0.11 in cam1.
  EXPECT_NEAR((d.calibration.T_right_left.translation() - Eigen::Vector3d(-0.11, 0.0, 0.0)).norm(), 0.0, 1e-12);
  ASSERT_TRUE(d.ground_truth.has_value());
  ASSERT_EQ(d.ground_truth->size(), 2u);
  EXPECT_NEAR(d.ground_truth->at(1).stamp_s, 300e-9, 1e-15);
  EXPECT_NEAR(d.ground_truth->at(1).T_world_cam.translation().x(), 1.5, 1e-12);
  // q = (w 0, x 0, y 0, z 1): half a turn about z.
  EXPECT_NEAR(d.ground_truth->at(1).T_world_cam.linear()(0, 0), -1.0, 1e-12);
}

TEST(EurocReader, PrefersTheTumGroundTruth) {
  TempDir dir;
  write_euroc(dir.path());
  write(dir.path() / "groundtruth.txt", "# timestamp tx ty tz qx qy qz qw\n0.0000001 9 8 7 0 0 0 1\n");
  const auto dataset = read_euroc(dir.path());
  ASSERT_TRUE(dataset.ok()) << dataset.error();
  EXPECT_EQ(dataset.value().ground_truth_file.filename(), "groundtruth.txt");
  EXPECT_DOUBLE_EQ(dataset.value().ground_truth->front().T_world_cam.translation().x(), 9.0);
}

TEST(EurocReader, BadInputNamesTheFileAndField) {
  {
    TempDir dir;
    write_euroc(dir.path());
    std::string yaml = sensor_yaml(0.11);
    yaml.replace(yaml.find("intrinsics: [50.0, 51.0, 32.0, 24.0]"), 36, "intrinsics: [50.0, 51.0, 32.0]");
    write(dir.path() / "mav0/cam1/sensor.yaml", yaml);
    const auto dataset = read_euroc(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("cam1/sensor.yaml: field 'intrinsics'"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    write_euroc(dir.path());
    write(dir.path() / "mav0/cam0/data.csv", "#timestamp [ns],filename\n100,100.png\nabc,200.png\n");
    const auto dataset = read_euroc(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("cam0/data.csv:3:"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    write_euroc(dir.path());
    write(dir.path() / "mav0/cam1/sensor.yaml", sensor_yaml(0.0));  // both cameras in one place
    const auto dataset = read_euroc(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("field 'T_BS'"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    write_euroc(dir.path());
    write(dir.path() / "groundtruth_cam0_euroc.txt", "100,1,2,3,1,0,0\n");
    const auto dataset = read_euroc(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("groundtruth_cam0_euroc.txt:1:"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    const auto dataset = read_stereo_dataset(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("neither a EuRoC"), std::string::npos) << dataset.error();
  }
}

TEST(EurocReader, RectifiesToAHorizontalRig) {
  TempDir dir;
  write_euroc(dir.path());
  const auto dataset = read_euroc(dir.path());
  ASSERT_TRUE(dataset.ok()) << dataset.error();
  const Rectifier rectifier(dataset.value().calibration);
  EXPECT_NEAR(rectifier.rig().baseline_m, 0.11, 1e-9);
  cv::Mat left(48, 64, CV_8UC1, cv::Scalar(50)), left_rect, right_rect;
  EXPECT_TRUE(rectifier.rectify(left, left, left_rect, right_rect));
  EXPECT_EQ(left_rect.size(), cv::Size(64, 48));
  EXPECT_FALSE(rectifier.rectify(cv::Mat(10, 10, CV_8UC1), left, left_rect, right_rect));
}

void write_kitti(const fs::path& dir, int frames) {
  write(dir / "calib.txt",
        "P0: 700 0 600 0 0 700 180 0 0 0 1 0\nP1: 700 0 600 -378 0 700 180 0 0 0 1 0\n"
        "P2: 700 0 600 44 0 700 180 0.2 0 0 1 0.003\n");
  std::string times;
  std::string poses;
  for (int i = 0; i < frames; ++i) {
    char name[16];
    std::snprintf(name, sizeof name, "%06d.png", i);
    write_png(dir / "image_0" / name, 80, 40);
    write_png(dir / "image_1" / name, 80, 40);
    times += std::to_string(0.1 * i) + "\n";
    poses += "1 0 0 0 0 1 0 0 0 0 1 " + std::to_string(0.5 * i) + "\n";
  }
  write(dir / "times.txt", times);
  write(dir / "poses.txt", poses);
}

TEST(KittiReader, ReadsProjectionsTimesAndPoses) {
  TempDir dir;
  write_kitti(dir.path(), 3);
  const auto dataset = read_stereo_dataset(dir.path());
  ASSERT_TRUE(dataset.ok()) << dataset.error();
  const StereoDataset& d = dataset.value();
  EXPECT_EQ(d.layout, DatasetLayout::kitti);
  ASSERT_EQ(d.frames.size(), 3u);
  EXPECT_EQ(d.frames[2].left.filename(), "000002.png");
  EXPECT_NEAR(d.frames[2].stamp_s, 0.2, 1e-9);
  EXPECT_TRUE(d.calibration.rectified);
  EXPECT_EQ(d.calibration.left.size, cv::Size(80, 40));
  EXPECT_NEAR(d.calibration.T_right_left.translation().x(), -0.54, 1e-12);
  const Rectifier rectifier(d.calibration);
  EXPECT_NEAR(rectifier.rig().baseline_m, 0.54, 1e-12);
  EXPECT_DOUBLE_EQ(rectifier.rig().cx, 600.0);
  ASSERT_TRUE(d.ground_truth.has_value());
  EXPECT_NEAR(d.ground_truth->at(2).T_world_cam.translation().z(), 1.0, 1e-12);
  EXPECT_NEAR(d.ground_truth->at(2).stamp_s, 0.2, 1e-9);
}

TEST(KittiReader, BadInputNamesTheFileAndLine) {
  {
    TempDir dir;
    write_kitti(dir.path(), 2);
    write(dir.path() / "calib.txt", "P0: 700 0 600 0 0 700 180 0 0 0 1 0\n");
    const auto dataset = read_kitti(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("calib.txt: field 'P1': missing"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    write_kitti(dir.path(), 2);
    write(dir.path() / "calib.txt", "P0: 700 0 600 0 0 700 180 0 0 0 1 0\nP1: 700 0 600 -378 0 700 180 0 0 0 1\n");
    const auto dataset = read_kitti(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("calib.txt:2: P1: expected 12 numbers"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    write_kitti(dir.path(), 3);
    write(dir.path() / "times.txt", "0.0\n0.2\n0.1\n");
    const auto dataset = read_kitti(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("times.txt:3: times must increase"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    write_kitti(dir.path(), 3);
    fs::remove(dir.path() / "image_1" / "000001.png");
    const auto dataset = read_kitti(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("image_1/000001.png: missing"), std::string::npos) << dataset.error();
  }
  {
    TempDir dir;
    write_kitti(dir.path(), 3);
    write(dir.path() / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0.5\n");
    const auto dataset = read_kitti(dir.path());
    ASSERT_FALSE(dataset.ok());
    EXPECT_NE(dataset.error().find("poses.txt: 2 poses for 3 frames"), std::string::npos) << dataset.error();
  }
}

}  // namespace
