// The simulator writes a complete, self-consistent recording in the documented format, and the
// same inputs always give the same bytes.
#include "sim_test_support.hpp"

#include "rankslam/hal/candump.hpp"
#include "rankslam/nav/wheel_frame.hpp"
#include "rankslam/sim/scene.hpp"
#include "rankslam/sim/simulator.hpp"

#ifdef RANKSLAM_SIM_TEST_REPLAY
#include "rankslam/replay/recording.hpp"
#endif

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <fstream>
#include <regex>

namespace rankslam::sim {
namespace {

using testing::TempDir;
namespace fs = std::filesystem;

TEST(SimCatalog, EveryNamedSceneHasADescriptionAndBuilds) {
  const auto names = scene_names();
  ASSERT_EQ(names.size(), 5U);
  for (const auto& expected : {"office", "zigzag-plain", "poster-wall", "dark-office", "corridor-loop"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), expected), names.end()) << expected;
  }
  for (const auto& name : names) {
    EXPECT_GT(scene_description(name).size(), 40U) << name;
    std::string error;
    const auto scene = make_scene(name, 1, &error);
    ASSERT_TRUE(scene) << name << ": " << error;
    EXPECT_FALSE(scene->surfaces.empty());
    EXPECT_GT(scene->default_frames, 0);
  }
  EXPECT_TRUE(scene_description("kitchen").empty());
  std::string error;
  EXPECT_FALSE(make_scene("kitchen", 1, &error));
  EXPECT_NE(error.find("kitchen"), std::string::npos);
}

TEST(SimOptions, BadOptionsAreRejectedWithAMessage) {
  TempDir dir("options");
  SimulationSummary summary;
  auto options = testing::options_for("kitchen", dir.path(), 2);
  auto error = simulate_recording(options, &summary);
  EXPECT_NE(error.find("unknown scene 'kitchen'"), std::string::npos) << error;
  EXPECT_FALSE(fs::exists(dir.path())) << "nothing may be written for a rejected run";

  options = testing::options_for("office", dir.path(), -3);
  EXPECT_NE(simulate_recording(options, nullptr).find("frames"), std::string::npos);
  options = testing::options_for("office", dir.path(), 2);
  options.motion_blur = true;
  options.motion_blur_samples = 4;
  EXPECT_NE(simulate_recording(options, nullptr).find("motion_blur_samples"), std::string::npos);
  options = testing::options_for("office", dir.path(), 2);
  options.min_depth_m = 3.0;
  options.max_depth_m = 2.0;
  EXPECT_NE(simulate_recording(options, nullptr).find("depth range"), std::string::npos);
  options = testing::options_for("office", "", 2);
  EXPECT_FALSE(simulate_recording(options, nullptr).empty());

  // A folder that is not empty is refused, and so is a path below a regular file.
  fs::create_directories(dir.path());
  std::ofstream(dir / "keep.txt") << "x";
  options = testing::options_for("office", dir.path(), 2);
  error = simulate_recording(options, nullptr);
  EXPECT_NE(error.find("not empty"), std::string::npos) << error;
  options = testing::options_for("office", dir / "keep.txt" / "sub", 2);
  error = simulate_recording(options, nullptr);
  EXPECT_NE(error.find("cannot create"), std::string::npos) << error;
}

// Frames of each scene in the consistency test; the corridor needs 7 for three fisheye images.
int frames_for(const std::string& scene) { return scene == "corridor-loop" ? 7 : 3; }

class SimRecording : public ::testing::TestWithParam<std::string> {};

TEST_P(SimRecording, WritesAConsistentRecording) {
  const std::string scene = GetParam();
  const int frames = frames_for(scene);
  TempDir dir(scene);
  SimulationSummary summary;
  ASSERT_EQ(simulate_recording(testing::options_for(scene, dir.path(), frames), &summary), "");
  EXPECT_EQ(summary.frames_written, frames);
  EXPECT_EQ(summary.scene, scene);
  EXPECT_GT(summary.seconds, 0.0);
  EXPECT_GT(summary.frames_per_second, 0.0);

  const std::regex stamp_format(R"(\d{10}\.\d{6})");
  auto check_list = [&](const std::string& list, const std::string& folder, int divider, int type, int width,
                        int height) {
    SCOPED_TRACE(list);
    const auto lines = testing::read_all_lines(dir / list);
    ASSERT_GE(lines.size(), 2U);
    EXPECT_EQ(lines[0][0], '#');
    const auto rows = testing::read_rows(dir / list);
    ASSERT_EQ(static_cast<int>(rows.size()), (frames + divider - 1) / divider);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      ASSERT_EQ(rows[i].size(), 2U);
      EXPECT_TRUE(std::regex_match(rows[i][0], stamp_format)) << rows[i][0];
      const double expected = 1700000000.0 + static_cast<double>(i * static_cast<std::size_t>(divider)) / 30.0;
      EXPECT_NEAR(std::stod(rows[i][0]), expected, 1e-6);
      EXPECT_EQ(rows[i][1], folder + "/" + rows[i][0] + ".png");
      const cv::Mat image = cv::imread((dir / rows[i][1]).string(), cv::IMREAD_UNCHANGED);
      ASSERT_FALSE(image.empty()) << rows[i][1];
      EXPECT_EQ(image.type(), type);
      EXPECT_EQ(image.cols, width);
      EXPECT_EQ(image.rows, height);
    }
  };
  check_list("rgb.txt", "rgb", 1, CV_8UC3, 640, 480);
  check_list("depth.txt", "depth", 1, CV_16UC1, 640, 480);
  EXPECT_EQ(testing::read_rows(dir / "rgb.txt")[0][0], "1700000000.000000");
  EXPECT_EQ(testing::read_rows(dir / "rgb.txt")[1][0], "1700000000.033333");

  const auto associations = testing::read_rows(dir / "associations.txt");
  const auto rgb = testing::read_rows(dir / "rgb.txt");
  const auto depth = testing::read_rows(dir / "depth.txt");
  ASSERT_EQ(associations.size(), rgb.size());
  for (std::size_t i = 0; i < associations.size(); ++i) {
    ASSERT_EQ(associations[i].size(), 4U);
    EXPECT_EQ(associations[i][0], rgb[i][0]);
    EXPECT_EQ(associations[i][1], rgb[i][1]);
    EXPECT_EQ(associations[i][2], depth[i][0]);
    EXPECT_EQ(associations[i][3], depth[i][1]);
  }

  // Ground truth: TUM header, one unit-quaternion pose per frame at the frame's stamp.
  const auto gt_lines = testing::read_all_lines(dir / "groundtruth.txt");
  EXPECT_NE(std::find(gt_lines.begin(), gt_lines.end(), "# timestamp tx ty tz qx qy qz qw"), gt_lines.end());
  const auto gt = testing::read_rows(dir / "groundtruth.txt");
  ASSERT_EQ(static_cast<int>(gt.size()), frames);
  for (std::size_t i = 0; i < gt.size(); ++i) {
    ASSERT_EQ(gt[i].size(), 8U);
    EXPECT_EQ(gt[i][0], rgb[i][0]);
    const Eigen::Vector4d q(std::stod(gt[i][4]), std::stod(gt[i][5]), std::stod(gt[i][6]), std::stod(gt[i][7]));
    EXPECT_NEAR(q.norm(), 1.0, 1e-8);
  }

  // calibration.yaml: every documented key, parsed with yaml-cpp.
  const YAML::Node root = YAML::LoadFile((dir / "calibration.yaml").string());
  EXPECT_DOUBLE_EQ(root["depth_scale"].as<double>(), 5000.0);
  const YAML::Node camera = root["cameras"]["rgb"];
  ASSERT_TRUE(camera);
  EXPECT_EQ(camera["model"].as<std::string>(), "pinhole");
  EXPECT_EQ(camera["width"].as<int>(), 640);
  EXPECT_EQ(camera["height"].as<int>(), 480);
  EXPECT_EQ(camera["intrinsics"].as<std::vector<double>>(), (std::vector<double>{517.3, 516.5, 318.6, 255.3}));
  EXPECT_EQ(camera["distortion"].as<std::vector<double>>(), std::vector<double>(5, 0.0));
  EXPECT_EQ(camera["T_base_cam"]["translation"].as<std::vector<double>>().size(), 3U);
  EXPECT_EQ(camera["T_base_cam"]["rotation_xyzw"].as<std::vector<double>>().size(), 4U);
  const hal::Calibration calibration = testing::read_calibration(dir / "calibration.yaml");
  // A camera looking forward: optical z is base x, optical x is base −y.
  EXPECT_TRUE((calibration.rgb.T_base_cam.linear() * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d::UnitX(), 1e-9));
  EXPECT_TRUE((calibration.rgb.T_base_cam.linear() * Eigen::Vector3d::UnitX()).isApprox(-Eigen::Vector3d::UnitY(), 1e-9));

  const bool dark = scene == "dark-office";
  const bool corridor = scene == "corridor-loop";
  EXPECT_EQ(fs::exists(dir / "ir.txt"), dark);
  EXPECT_EQ(fs::exists(dir / "fisheye.txt"), corridor);
  EXPECT_EQ(fs::exists(dir / "can.log"), corridor);
  EXPECT_EQ(fs::exists(dir / "slip.txt"), corridor);
  EXPECT_EQ(static_cast<bool>(root["wheels"]), corridor);
  EXPECT_EQ(static_cast<bool>(root["cameras"]["fisheye"]), corridor);
  if (dark) {
    check_list("ir.txt", "ir", 1, CV_8UC1, 640, 480);
  }
  if (corridor) {
    check_list("fisheye.txt", "fisheye", 3, CV_8UC3, 960, 600);
    const YAML::Node fisheye = root["cameras"]["fisheye"];
    EXPECT_EQ(fisheye["model"].as<std::string>(), "fisheye");
    EXPECT_EQ(fisheye["distortion"].as<std::vector<double>>().size(), 4U);
    ASSERT_TRUE(calibration.fisheye);
    EXPECT_EQ(calibration.fisheye->width, 960);
    ASSERT_TRUE(calibration.wheels);
    EXPECT_EQ(calibration.wheels->can_id, 0x101U);
    EXPECT_DOUBLE_EQ(calibration.wheels->radius_m, 0.05);
    EXPECT_DOUBLE_EQ(calibration.wheels->track_width_m, 0.30);
    EXPECT_EQ(calibration.wheels->ticks_per_revolution, 4096);
    // can.log: candump -l frames at 100 Hz over the recording's span.
    const auto lines = testing::read_all_lines(dir / "can.log");
    ASSERT_EQ(lines.size(), 21U);  // 0 … 0.2 s
    for (std::size_t i = 0; i < lines.size(); ++i) {
      const auto frame = hal::parse_candump_line(lines[i]);
      ASSERT_TRUE(frame) << lines[i];
      EXPECT_EQ(frame->id, 0x101U);
      EXPECT_EQ(frame->stamp_ns, 1'700'000'000'000'000'000LL + static_cast<std::int64_t>(i) * 10'000'000);
      EXPECT_TRUE(nav::decode_wheel_ticks(*frame));
    }
  }

#ifdef RANKSLAM_SIM_TEST_REPLAY
  // The product's recording reader indexes it without complaint.
  replay::Recording recording;
  ASSERT_EQ(replay::open_recording(dir.path(), recording), "");
  EXPECT_TRUE(recording.warnings.empty()) << recording.warnings.front();
  EXPECT_EQ(static_cast<int>(recording.frames.size()), frames);
  EXPECT_DOUBLE_EQ(recording.calibration.rgb.fx, 517.3);
  EXPECT_TRUE(recording.calibration.rgb.T_base_cam.isApprox(calibration.rgb.T_base_cam, 1e-12));
  EXPECT_EQ(recording.calibration.fisheye.has_value(), corridor);
  EXPECT_EQ(recording.calibration.wheels.has_value(), corridor);
  if (corridor) {
    EXPECT_EQ(recording.fisheye.size(), 3U);
    EXPECT_EQ(recording.can_frames.size(), 21U);
    EXPECT_EQ(recording.calibration.wheels->can_id, 0x101U);
  }
  if (dark) {
    for (const auto& frame : recording.frames) EXPECT_FALSE(frame.ir_file.empty());
  }
#endif
}

INSTANTIATE_TEST_SUITE_P(Scenes, SimRecording,
                         ::testing::Values("office", "zigzag-plain", "poster-wall", "dark-office", "corridor-loop"),
                         [](const auto& test_info) {
                           std::string name = test_info.param;
                           std::replace(name.begin(), name.end(), '-', '_');
                           return name;
                         });

// Every file of two recordings, byte for byte.
void expect_identical_folders(const fs::path& a, const fs::path& b) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(a)) {
    if (entry.is_regular_file()) files.push_back(fs::relative(entry.path(), a));
  }
  std::size_t count_b = 0;
  for (const auto& entry : fs::recursive_directory_iterator(b)) count_b += entry.is_regular_file() ? 1 : 0;
  ASSERT_EQ(files.size(), count_b);
  ASSERT_GT(files.size(), 5U);
  const auto bytes = testing::read_bytes;
  for (const auto& file : files) {
    ASSERT_TRUE(fs::exists(b / file)) << file;
    EXPECT_TRUE(bytes(a / file) == bytes(b / file)) << file << " differs";
  }
}

TEST(SimDeterminism, SameInputsGiveIdenticalBytesWhateverTheThreadCount) {
  for (const std::string scene : {"corridor-loop", "dark-office"}) {
    SCOPED_TRACE(scene);
    TempDir a(scene + "_a");
    TempDir b(scene + "_b");
    auto options = testing::options_for(scene, a.path(), 4);
    options.seed = 7;
    options.threads = 2;
    ASSERT_EQ(simulate_recording(options, nullptr), "");
    options.out_dir = b.path();
    options.threads = 1;
    ASSERT_EQ(simulate_recording(options, nullptr), "");
    expect_identical_folders(a.path(), b.path());
  }
}

TEST(SimDeterminism, SeedChangesAppearanceNotGroundTruth) {
  TempDir a("seed_a");
  TempDir b("seed_b");
  auto options = testing::options_for("office", a.path(), 2);
  options.seed = 1;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.out_dir = b.path();
  options.seed = 2;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  const auto rgb = testing::read_rows(a / "rgb.txt");
  const cv::Mat image_a = cv::imread((a / rgb[1][1]).string());
  const cv::Mat image_b = cv::imread((b / rgb[1][1]).string());
  EXPECT_GT(cv::norm(image_a, image_b, cv::NORM_L1) / static_cast<double>(image_a.total()), 3.0);
  EXPECT_EQ(testing::read_rows(a / "groundtruth.txt"), testing::read_rows(b / "groundtruth.txt"));
}

TEST(SimDeterminism, SceneSeedPaintsTheSceneWhateverTheNoiseSeed) {
  // The office's second colour image, simulated with these seeds.
  const auto colour = [](std::uint64_t seed, std::uint64_t scene_seed, bool sensor_noise) {
    TempDir dir("scene_seed");
    auto options = testing::options_for("office", dir.path(), 2);
    options.seed = seed;
    options.scene_seed = scene_seed;
    options.sensor_noise = sensor_noise;
    EXPECT_EQ(simulate_recording(options, nullptr), "");
    return testing::image_of(dir.path(), "rgb.txt", 1, cv::IMREAD_COLOR);
  };
  // Without sensor noise the images are the paint alone: the scene seed decides them.
  const cv::Mat image_a = colour(1, 0, false);
  const cv::Mat image_b = colour(2, 1, false);
  const cv::Mat image_c = colour(2, 0, false);
  ASSERT_FALSE(image_a.empty());
  EXPECT_EQ(cv::norm(image_a, image_b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(image_a, image_c, cv::NORM_L1) / static_cast<double>(image_a.total()), 3.0);
  // With noise, the same paint under the other seed's noise: closer than other paint.
  const cv::Mat image_d = colour(1, 0, true);
  const cv::Mat image_e = colour(2, 1, true);
  EXPECT_GT(cv::norm(image_d, image_e, cv::NORM_INF), 0.0);
  EXPECT_LT(cv::norm(image_d, image_e, cv::NORM_L1), 0.5 * cv::norm(image_a, image_c, cv::NORM_L1));
}

TEST(SimDeterminism, MotionBlurIsDeterministicAndBlurs) {
  TempDir sharp("sharp");
  TempDir blur_a("blur_a");
  TempDir blur_b("blur_b");
  auto options = testing::options_for("poster-wall", sharp.path(), 2);
  options.first_frame = 0;  // sweeping fastest across the wall
  options.sensor_noise = false;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.motion_blur = true;
  options.out_dir = blur_a.path();
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.out_dir = blur_b.path();
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  expect_identical_folders(blur_a.path(), blur_b.path());
  // Blur lowers the image's gradient energy; depth is taken at the frame time and unchanged.
  const auto rgb = testing::read_rows(sharp / "rgb.txt");
  auto gradient_energy = [](const cv::Mat& image) {
    cv::Mat gray;
    cv::Mat dx;
    cv::Mat dy;
    image.convertTo(gray, CV_32F);
    cv::Sobel(gray, dx, CV_32F, 1, 0);
    cv::Sobel(gray, dy, CV_32F, 0, 1);
    return cv::norm(dx, cv::NORM_L2SQR) + cv::norm(dy, cv::NORM_L2SQR);
  };
  const cv::Mat sharp_image = cv::imread((sharp / rgb[0][1]).string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat blurred_image = cv::imread((blur_a / rgb[0][1]).string(), cv::IMREAD_GRAYSCALE);
  EXPECT_LT(gradient_energy(blurred_image), 0.8 * gradient_energy(sharp_image));
  const auto depth = testing::read_rows(sharp / "depth.txt");
  const cv::Mat depth_sharp = cv::imread((sharp / depth[0][1]).string(), cv::IMREAD_UNCHANGED);
  const cv::Mat depth_blur = cv::imread((blur_a / depth[0][1]).string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(cv::norm(depth_sharp, depth_blur, cv::NORM_INF), 0.0);
}

TEST(SimRecordingStretch, LaterStretchMatchesTheSameFramesOfALongerRun) {
  TempDir whole("whole");
  TempDir part("part");
  auto options = testing::options_for("corridor-loop", whole.path(), 8);
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  options.out_dir = part.path();
  options.first_frame = 5;
  options.frames = 3;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  const auto rgb_part = testing::read_rows(part / "rgb.txt");
  ASSERT_EQ(rgb_part.size(), 3U);
  EXPECT_EQ(rgb_part[0][0], "1700000000.166667");
  const auto bytes = testing::read_bytes;
  for (const auto& row : rgb_part) EXPECT_TRUE(bytes(whole / row[1]) == bytes(part / row[1])) << row[1];
  // Fisheye only on the 10 Hz grid (frame 6), ground truth and wheel frames for the stretch.
  const auto fisheye = testing::read_rows(part / "fisheye.txt");
  ASSERT_EQ(fisheye.size(), 1U);
  EXPECT_EQ(fisheye[0][0], "1700000000.200000");
  const auto gt_whole = testing::read_rows(whole / "groundtruth.txt");
  const auto gt_part = testing::read_rows(part / "groundtruth.txt");
  ASSERT_EQ(gt_part.size(), 3U);
  for (std::size_t i = 0; i < 3; ++i) EXPECT_EQ(gt_part[i], gt_whole[5 + i]);
  const auto can_whole = testing::read_all_lines(whole / "can.log");
  const auto can_part = testing::read_all_lines(part / "can.log");
  ASSERT_FALSE(can_part.empty());
  EXPECT_EQ(can_part.front(), can_whole[17]);  // 0.17 s, the first 10 ms step at or after 0.1667 s
  EXPECT_EQ(can_part.back(), can_whole.back());
}

TEST(SimRecordingStretch, LongRunsRepeatTheMotion) {
  TempDir dir("loop");
  auto options = testing::options_for("office", dir.path(), 302);
  options.images = false;
  ASSERT_EQ(simulate_recording(options, nullptr), "");
  EXPECT_FALSE(fs::exists(dir / "rgb.txt")) << "no image lists without images";
  const auto gt = testing::read_groundtruth(dir / "groundtruth.txt");
  ASSERT_EQ(gt.size(), 302U);
  EXPECT_NEAR(gt[300].stamp_s - gt[0].stamp_s, 10.0, 1e-6);
  EXPECT_TRUE(gt[300].T.isApprox(gt[0].T, 1e-6));
  EXPECT_TRUE(gt[301].T.isApprox(gt[1].T, 1e-6));
  EXPECT_FALSE(gt[150].T.isApprox(gt[0].T, 1e-3));
}

}  // namespace
}  // namespace rankslam::sim
