#include "rankslam/replay/recording.hpp"

#include "recording_fixture.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <fstream>

namespace rankslam::replay {
namespace {

namespace fs = std::filesystem;

TEST(Recording, ReadsAssociationsAndCalibration) {
  const fs::path root = test::write_small_recording("rankslam_rec_assoc", 5, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ASSERT_EQ(recording.frames.size(), 5U);
  EXPECT_EQ(recording.calibration.rgb.width, 64);
  EXPECT_DOUBLE_EQ(recording.calibration.rgb.fx, 50.0);
  EXPECT_NEAR(recording.calibration.rgb.T_base_cam.translation().z(), 0.5, 1e-12);
  // Optical z (forward) is base x for this mounting.
  const Eigen::Vector3d forward = recording.calibration.rgb.T_base_cam.linear() * Eigen::Vector3d::UnitZ();
  EXPECT_NEAR(forward.x(), 1.0, 1e-9);
  EXPECT_FALSE(recording.ground_truth.has_value());
}

TEST(Recording, AssociatesByNearestStampWithoutAssociationsFile) {
  const fs::path root = test::write_small_recording("rankslam_rec_nearest", 6, false, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ASSERT_EQ(recording.frames.size(), 6U);
  for (const auto& frame : recording.frames) EXPECT_NEAR(frame.depth_stamp_s - frame.rgb_stamp_s, 0.004, 1e-6);
}

TEST(Recording, AssociationIsGreedyByGapAndOneToOne) {
  const std::vector<double> a = {1.000, 1.030, 1.100};
  const std::vector<double> b = {1.010, 1.025, 1.500};
  const auto pairs = hal::associate_stamps(a, b, 0.02);
  ASSERT_EQ(pairs.size(), 2U);
  // 1.030-1.025 (gap 0.005) is taken first, leaving 1.000-1.010 (0.010); 1.100 has nothing near.
  EXPECT_EQ(pairs[0].first_index, 0U);
  EXPECT_EQ(pairs[0].second_index, 0U);
  EXPECT_EQ(pairs[1].first_index, 1U);
  EXPECT_EQ(pairs[1].second_index, 1U);
}

TEST(Recording, TumCalibrationFromFolderNameOrGroundTruthHeader) {
  const fs::path named = test::write_small_recording("rankslam_rec_fr2_desk", 2, true, false);
  Recording recording;
  ASSERT_EQ(open_recording(named, recording), "");
  EXPECT_DOUBLE_EQ(recording.calibration.rgb.fx, 520.9);

  const fs::path by_header = test::write_small_recording("rankslam_rec_unnamed", 2, true, false);
  std::string error = open_recording(by_header, recording);
  EXPECT_NE(error.find("calibration.yaml"), std::string::npos) << error;
  std::ofstream(by_header / "groundtruth.txt") << "# ground truth trajectory\n# file: 'rgbd_dataset_freiburg3_long.bag'\n"
                                                 "# timestamp tx ty tz qx qy qz qw\n100.0 0 0 0 0 0 0 1\n";
  ASSERT_EQ(open_recording(by_header, recording), "");
  EXPECT_DOUBLE_EQ(recording.calibration.rgb.fx, 535.4);
  EXPECT_TRUE(recording.ground_truth.has_value());
}

TEST(Recording, CalibrationErrorsNameTheField) {
  const fs::path root = test::write_small_recording("rankslam_rec_badcal", 2, true, false);
  std::ofstream(root / "calibration.yaml") << "cameras:\n  rgb:\n    model: pinhole\n    width: 64\n    height: 48\n"
                                              "    intrinsics: [50.0, 50.0, 32.0]\n";
  Recording recording;
  const std::string error = open_recording(root, recording);
  EXPECT_NE(error.find("cameras.rgb.intrinsics"), std::string::npos) << error;
  EXPECT_NE(error.find("calibration.yaml"), std::string::npos) << error;

  std::ofstream(root / "calibration.yaml") << "cameras:\n  rgb:\n    model: orthographic\n";
  EXPECT_NE(open_recording(root, recording).find("cameras.rgb.model"), std::string::npos);

  const std::string camera = "cameras:\n  rgb:\n    model: pinhole\n    width: 64\n    height: 48\n"
                             "    intrinsics: [50.0, 50.0, 32.0, 24.0]\n";
  std::ofstream(root / "calibration.yaml") << "depth_noise_per_m: -0.001\n" << camera;
  EXPECT_NE(open_recording(root, recording).find("depth_noise_per_m"), std::string::npos);
  std::ofstream(root / "calibration.yaml") << "depth_noise_per_m: 0.002\n" << camera;
  ASSERT_EQ(open_recording(root, recording), "");
  EXPECT_DOUBLE_EQ(recording.calibration.depth_noise_per_m, 0.002);
  std::ofstream(root / "calibration.yaml") << camera;
  ASSERT_EQ(open_recording(root, recording), "");
  EXPECT_DOUBLE_EQ(recording.calibration.depth_noise_per_m, 1.425e-3);  // the Kinect v1's
}

TEST(Recording, MalformedListLineIsNamedWithFileAndLine) {
  const fs::path root = test::write_small_recording("rankslam_rec_badlist", 3, false, true);
  std::ofstream(root / "depth.txt", std::ios::app) << "not-a-stamp\n";
  Recording recording;
  const std::string error = open_recording(root, recording);
  EXPECT_NE(error.find("depth.txt:5"), std::string::npos) << error;
}

TEST(Recording, ReadsCanLogAndIrStream) {
  const fs::path root = test::write_small_recording("rankslam_rec_can", 3, true, true);
  std::ofstream(root / "can.log") << "(100.010000) can0 101#0100000200000300\n"
                                     "(100.000000) can0 101#0000000000000200\n"
                                     "this line is broken\n";
  fs::create_directories(root / "ir");
  std::ofstream(root / "ir.txt") << "100.001000 ir/a.png\n";
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ASSERT_EQ(recording.can_frames.size(), 2U);
  EXPECT_LT(recording.can_frames[0].stamp_ns, recording.can_frames[1].stamp_ns);
  // The broken line, and the stamps out of order.
  ASSERT_EQ(recording.warnings.size(), 2U);
  EXPECT_NE(recording.warnings[0].find("can.log:3: not a candump -l frame"), std::string::npos) << recording.warnings[0];
  EXPECT_NE(recording.warnings[1].find("can.log: stamps go backwards 1 times (by up to 0.010000 s)"), std::string::npos)
      << recording.warnings[1];
  EXPECT_EQ(recording.frames[0].ir_file, "ir/a.png");
  EXPECT_TRUE(recording.frames[1].ir_file.empty());
}

TEST(Recording, MissingDirectoryIsAnError) {
  Recording recording;
  EXPECT_NE(open_recording("/nonexistent/recording", recording).find("/nonexistent/recording"), std::string::npos);
}

TEST(Recording, ARepeatedColourStampIsReplayedOnceAndNamed) {
  const fs::path root = test::write_small_recording("rankslam_rec_duplicate", 4, true, true);
  std::string text;
  {
    std::ifstream in(root / "associations.txt");
    std::string line;
    for (int i = 0; std::getline(in, line); ++i) text += line + "\n" + (i == 1 ? line + "\n" : "");
  }
  std::ofstream(root / "associations.txt", std::ios::trunc) << text;
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  EXPECT_EQ(recording.frames.size(), 4U);
  ASSERT_EQ(recording.warnings.size(), 1U);
  EXPECT_EQ(recording.warnings[0], (root / "associations.txt").string() + ":3: colour stamp already on line 2, line dropped");
}

TEST(Recording, ListFilesThatAreNotRegularFilesAreRefusedByName) {
  for (const char* name : {"associations.txt", "calibration.yaml", "groundtruth.txt", "can.log", "ir.txt", "fisheye.txt"}) {
    const fs::path root = test::write_small_recording("rankslam_rec_fifo", 3, true, true);
    fs::remove(root / name);
    ASSERT_EQ(::mkfifo((root / name).c_str(), 0600), 0);
    Recording recording;
    EXPECT_EQ(open_recording(root, recording), (root / name).string() + ": a FIFO, not a regular file") << name;
  }
  const fs::path root = test::write_small_recording("rankslam_rec_fifo_rgb", 3, false, true);
  fs::remove(root / "rgb.txt");
  fs::create_directory(root / "rgb.txt");
  Recording recording;
  EXPECT_EQ(open_recording(root, recording), (root / "rgb.txt").string() + ": a directory, not a regular file");
}

TEST(Recording, ASymlinkLoopIsAnErrorNamingTheFile) {
  const fs::path root = test::write_small_recording("rankslam_rec_loop", 3, true, true);
  fs::remove(root / "associations.txt");
  fs::create_symlink("associations.txt", root / "associations.txt");
  Recording recording;
  const std::string error = open_recording(root, recording);
  EXPECT_EQ(error.rfind((root / "associations.txt").string() + ": ", 0), 0U) << error;
}

TEST(Recording, StampsBeyondTheNanosecondClockAreMalformedLines) {
  const fs::path root = test::write_small_recording("rankslam_rec_stamp", 3, true, true);
  std::ofstream(root / "associations.txt", std::ios::app) << "1e300 rgb/a.png 1e300 depth/a.png\n";
  Recording recording;
  EXPECT_EQ(open_recording(root, recording), (root / "associations.txt").string() +
                                                 ":4: expected 'rgb_stamp rgb_file depth_stamp depth_file'");
}

}  // namespace
}  // namespace rankslam::replay
