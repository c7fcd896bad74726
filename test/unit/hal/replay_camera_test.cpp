#include "rankslam/replay/replay_camera.hpp"

#include "rankslam/hal/nearest_image.hpp"

#include "recording_fixture.hpp"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <fstream>
#include <limits>
#include <thread>

namespace rankslam::replay {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

std::vector<hal::RgbdFrame> replay_all(ReplayDepthCamera& camera) {
  std::vector<hal::RgbdFrame> frames;
  hal::RgbdFrame frame;
  for (;;) {
    const auto status = camera.read(frame, milliseconds(2000));
    if (status == hal::ReadStatus::kEndOfStream) break;
    EXPECT_EQ(status, hal::ReadStatus::kOk);
    if (status != hal::ReadStatus::kOk) break;
    hal::RgbdFrame copy = frame;
    copy.rgb = frame.rgb.clone();
    copy.depth = frame.depth.clone();
    frames.push_back(copy);
  }
  return frames;
}

TEST(ReplayCamera, DeliversEveryFrameInOrderWithDecodedImages) {
  const fs::path root = test::write_small_recording("rankslam_replay_order", 12, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ReplayDepthCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  const auto frames = replay_all(camera);
  ASSERT_EQ(frames.size(), 12U);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].sequence, i);
    EXPECT_EQ(frames[i].rgb.type(), CV_8UC3);
    EXPECT_EQ(frames[i].depth.type(), CV_16UC1);
    EXPECT_EQ(frames[i].depth.at<unsigned short>(0, 0), 5000 + i);
    EXPECT_EQ(frames[i].rgb.at<cv::Vec3b>(0, 0)[2], 3 * i);
  }
  EXPECT_EQ(camera.counters().corrupt, 0U);
  EXPECT_EQ(camera.counters().delivered, 12U);
}

// Without decoding ahead, frame k + 1 is read from disk only when the consumer asks for it
// after frame k: deleting its images while the consumer holds frame k makes it missing, however
// long the consumer takes. (With decoding ahead it would already be decoded by then.)
TEST(ReplayCamera, WithoutDecodingAheadTheNextFrameIsReadOnlyWhenAskedFor) {
  const fs::path root = test::write_small_recording("rankslam_replay_no_ahead", 6, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ReplayOptions options;
  options.decode_ahead = false;
  ReplayDepthCamera camera(recording, options);
  ASSERT_EQ(camera.open(), "");
  hal::RgbdFrame frame;
  ASSERT_EQ(camera.read(frame, milliseconds(2000)), hal::ReadStatus::kOk);
  ASSERT_EQ(frame.sequence, 0U);
  std::this_thread::sleep_for(milliseconds(200));  // a slow consumer
  fs::remove(root / recording.frames[1].rgb_file);
  ASSERT_EQ(camera.read(frame, milliseconds(2000)), hal::ReadStatus::kOk);
  EXPECT_EQ(frame.sequence, 2U);
  EXPECT_EQ(camera.counters().corrupt, 1U);
  const auto rest = replay_all(camera);
  ASSERT_EQ(rest.size(), 3U);
  EXPECT_EQ(rest.back().sequence, 5U);
}

TEST(ReplayCamera, CorruptAndMissingImagesAreSkippedCountedAndNamed) {
  const fs::path root = test::write_small_recording("rankslam_replay_corrupt", 8, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  // Truncate one colour image to garbage, delete one depth image.
  const fs::path corrupt = root / recording.frames[2].rgb_file;
  std::ofstream(corrupt, std::ios::trunc) << "\x89PNG this is not an image";
  fs::remove(root / recording.frames[5].depth_file);
  // A PNG cut short after its header: the signature is right, the data is not.
  const fs::path truncated = root / recording.frames[6].rgb_file;
  fs::resize_file(truncated, 60);

  ReplayDepthCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  const auto frames = replay_all(camera);
  EXPECT_EQ(frames.size(), 5U);
  EXPECT_EQ(camera.counters().corrupt, 3U);
  const auto warnings = camera.take_warnings();
  ASSERT_EQ(warnings.size(), 3U);
  EXPECT_NE(warnings[2].find(recording.frames[6].rgb_file), std::string::npos) << warnings[2];
  EXPECT_NE(warnings[0].find(recording.frames[2].rgb_file), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[1].find(recording.frames[5].depth_file), std::string::npos) << warnings[1];
  for (const auto& frame : frames) {
    EXPECT_NE(frame.sequence, 2U);
    EXPECT_NE(frame.sequence, 5U);
    EXPECT_NE(frame.sequence, 6U);
  }
}

TEST(ReplayCamera, WrongImageSizeIsSkippedNotCrashed) {
  const fs::path root = test::write_small_recording("rankslam_replay_size", 3, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  cv::imwrite((root / recording.frames[1].depth_file).string(), cv::Mat(10, 10, CV_16UC1, cv::Scalar(1)));
  ReplayDepthCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  EXPECT_EQ(replay_all(camera).size(), 2U);
  EXPECT_EQ(camera.counters().corrupt, 1U);
}

TEST(ReplayCamera, MaxFramesAndPacedReplay) {
  const fs::path root = test::write_small_recording("rankslam_replay_rate", 10, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ReplayOptions options;
  options.max_frames = 6;
  options.rate = 4.0;  // 6 frames at 30 Hz / 4: about 40 ms in all
  ReplayDepthCamera camera(recording, options);
  ASSERT_EQ(camera.open(), "");
  EXPECT_EQ(camera.frame_count(), 6U);
  const auto frames = replay_all(camera);
  const auto counters = camera.counters();
  EXPECT_EQ(frames.size() + counters.dropped, 6U);
  EXPECT_EQ(counters.corrupt, 0U);
}

TEST(ReplayCamera, ImagesThatAreNoRegularFilesOrTooLargeAreSkippedCountedAndNamed) {
  const fs::path root = test::write_small_recording("rankslam_replay_irregular", 6, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  recording.frames[1].rgb_file = "rgb";
  ASSERT_EQ(::mkfifo((root / "rgb" / "fifo.png").c_str(), 0600), 0);
  recording.frames[2].rgb_file = "rgb/fifo.png";
  std::ofstream(root / "depth" / "sparse.png") << "x";
  fs::resize_file(root / "depth" / "sparse.png", std::uintmax_t{20} << 30U);
  recording.frames[3].depth_file = "depth/sparse.png";
  ReplayDepthCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  const auto frames = replay_all(camera);
  fs::remove(root / "depth" / "sparse.png");
  ASSERT_EQ(frames.size(), 3U);
  EXPECT_EQ(camera.counters().corrupt, 3U);
  const auto warnings = camera.take_warnings();
  ASSERT_EQ(warnings.size(), 3U);
  EXPECT_EQ(warnings[0], (root / "rgb").string() + ": a directory, not a regular file, frame 1 (rgb) skipped");
  EXPECT_EQ(warnings[1], (root / "rgb" / "fifo.png").string() + ": a FIFO, not a regular file, frame 2 (rgb/fifo.png) skipped");
  EXPECT_NE(warnings[2].find("sparse.png: 21474836480 bytes"), std::string::npos) << warnings[2];
}

TEST(ReplayCamera, SizeAndLayoutAreCheckedFromTheHeaderBeforeDecoding) {
  const fs::path root = test::write_small_recording("rankslam_replay_header", 4, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  // A colour PNG whose header declares 30000 x 30000 pixels (the decoder would allocate 2.7 GB).
  std::vector<unsigned char> png;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(48, 64, CV_8UC3, cv::Scalar(1, 2, 3)), png));
  const unsigned char size[] = {0x00, 0x00, 0x75, 0x30};
  std::copy(std::begin(size), std::end(size), png.begin() + 16);
  std::copy(std::begin(size), std::end(size), png.begin() + 20);
  std::ofstream(root / recording.frames[1].rgb_file, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  // A 16-bit depth image of three channels, which IMREAD_ANYDEPTH would turn into one.
  cv::imwrite((root / recording.frames[2].depth_file).string(), cv::Mat(48, 64, CV_16UC3, cv::Scalar(5000, 5000, 5000)));
  ReplayDepthCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  EXPECT_EQ(replay_all(camera).size(), 2U);
  EXPECT_EQ(camera.counters().corrupt, 2U);
  const auto warnings = camera.take_warnings();
  ASSERT_EQ(warnings.size(), 2U);
  EXPECT_NE(warnings[0].find(": 30000x30000 but the calibration says 64x48, frame 1"), std::string::npos) << warnings[0];
  EXPECT_NE(warnings[1].find(recording.frames[2].depth_file + ": 3 channels of 16 bits"), std::string::npos) << warnings[1];
}

TEST(ReplayCamera, RatesWhosePacingWouldOverflowAreRefused) {
  const fs::path root = test::write_small_recording("rankslam_replay_rates", 2, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  for (const double rate : {1e-300, 1e-4, 1e4, -1.0, std::numeric_limits<double>::infinity()}) {
    ReplayOptions options;
    options.rate = rate;
    ReplayDepthCamera camera(recording, options);
    EXPECT_NE(camera.open().find("replay rate must be 0"), std::string::npos) << rate;
  }
  for (const double rate : {0.0, kMinReplayRate, kMaxReplayRate}) {
    ReplayOptions options;
    options.rate = rate;
    ReplayDepthCamera camera(recording, options);
    EXPECT_EQ(camera.open(), "") << rate;
  }
}

}  // namespace
}  // namespace rankslam::replay

namespace rankslam::replay {
namespace {

using test::add_wide_images;

TEST(ReplayImageCamera, PlaysTheWideImagesInOrderAndSkipsACorruptOneByName) {
  const fs::path root = test::write_small_recording("rankslam_replay_wide", 3, true, true);
  add_wide_images(root, {100.0, 100.1, 100.2});
  std::ofstream(root / "fisheye/1.png", std::ios::trunc) << "not an image";
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ReplayImageCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  hal::ImageFrame frame;
  std::vector<std::uint32_t> sequences;
  while (camera.read(frame, milliseconds(2000)) == hal::ReadStatus::kOk) {
    sequences.push_back(frame.sequence);
    EXPECT_EQ(frame.image.type(), CV_8UC3);
    EXPECT_EQ(frame.image.at<cv::Vec3b>(0, 0)[0], 10 * frame.sequence);
    EXPECT_EQ(frame.stamp_ns, 100'000'000'000LL + 100'000'000LL * frame.sequence);
  }
  EXPECT_EQ(sequences, (std::vector<std::uint32_t>{0, 2}));
  EXPECT_EQ(camera.counters().corrupt, 1U);
  const auto warnings = camera.take_warnings();
  ASSERT_EQ(warnings.size(), 1U);
  EXPECT_NE(warnings[0].find("fisheye/1.png"), std::string::npos) << warnings[0];
}

TEST(ReplayImageCamera, ARecordingWithoutWideAngleCalibrationIsRefusedByName) {
  const fs::path root = test::write_small_recording("rankslam_replay_wide_uncalibrated", 2, true, true);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ReplayImageCamera camera(recording, {});
  EXPECT_NE(camera.open().find("cameras.fisheye"), std::string::npos);
}

// Frames at 100 + i/30 s, paired with the wide-angle images by a NearestImage with `max_gap_ns`:
// each frame's image sequence, -1 for none.
std::vector<int> paired_sequences(const Recording& recording, std::int64_t max_gap_ns,
                                  hal::NearestImageCounters& counters) {
  ReplayDepthCamera frames(recording, {});
  ReplayImageCamera camera(recording, {});
  EXPECT_EQ(frames.open(), "");
  EXPECT_EQ(camera.open(), "");
  hal::NearestImage nearest(camera, max_gap_ns);
  nearest.allocate(32, 24, CV_8UC3);
  std::vector<int> sequences;
  hal::RgbdFrame frame;
  while (frames.read(frame, milliseconds(2000)) == hal::ReadStatus::kOk) {
    const hal::ImageFrame* image = nearest.take(frame.stamp_ns, milliseconds(2000));
    sequences.push_back(image == nullptr ? -1 : static_cast<int>(image->sequence));
    if (image != nullptr) {
      EXPECT_EQ(image->image.at<cv::Vec3b>(0, 0)[1], 10 * image->sequence);
    }
  }
  counters = nearest.counters();
  return sequences;
}

// Images at 100.003 (frame 0), 100.045 (frame 1 is 11.7 ms away, frame 2 21.7 ms), 100.103
// (frame 3) and 100.5 (after every frame).
TEST(NearestImage, PairsEachImageWithTheNearestFrameWithinTheGapOnce) {
  const fs::path root = test::write_small_recording("rankslam_nearest_image", 9, true, true);
  add_wide_images(root, {100.003, 100.045, 100.103, 100.5});
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  hal::NearestImageCounters counters;
  EXPECT_EQ(paired_sequences(recording, 20'000'000, counters), (std::vector<int>{0, 1, -1, 2, -1, -1, -1, -1, -1}));
  EXPECT_EQ(counters.read, 4U);
  EXPECT_EQ(counters.paired, 3U);
  // A 50 ms gap: frame 2 now reaches image 2, which frame 3, nearer to it, then cannot have again.
  EXPECT_EQ(paired_sequences(recording, 50'000'000, counters), (std::vector<int>{0, 1, 2, -1, -1, -1, -1, -1, -1}));
  EXPECT_EQ(counters.paired, 3U);
}

}  // namespace
}  // namespace rankslam::replay

namespace rankslam::replay {
namespace {

// With a reader thread the camera is drained as fast as it delivers, the newest kHeld images
// kept: once the stream has ended, the last ones pair with their frames, the older ones were
// passed over, and the image handed out is a copy the reader cannot overwrite.
TEST(NearestImage, AReaderThreadKeepsTheNewestImagesForPairing) {
  const fs::path root = test::write_small_recording("rankslam_nearest_reader", 2, true, true);
  std::vector<double> stamps;
  for (int k = 0; k < 10; ++k) stamps.push_back(100.0 + 0.1 * k);
  test::add_wide_images(root, stamps);
  Recording recording;
  ASSERT_EQ(open_recording(root, recording), "");
  ReplayImageCamera camera(recording, {});
  ASSERT_EQ(camera.open(), "");
  hal::NearestImage nearest(camera, 20'000'000);
  nearest.allocate(32, 24, CV_8UC3);
  nearest.start_reader(milliseconds(100));
  for (int i = 0; i < 2000 && !nearest.ended(); ++i) std::this_thread::sleep_for(milliseconds(5));
  ASSERT_TRUE(nearest.ended());
  nearest.stop_reader();
  EXPECT_EQ(nearest.counters().read, 10U);
  EXPECT_EQ(nearest.counters().unpaired, 10U - hal::NearestImage::kHeld);
  EXPECT_EQ(nearest.take(100'500'000'000LL, milliseconds(0)), nullptr);  // passed over
  const hal::ImageFrame* image = nearest.take(100'800'000'000LL, milliseconds(0));
  ASSERT_NE(image, nullptr);
  EXPECT_EQ(image->sequence, 8U);
  EXPECT_EQ(image->image.at<cv::Vec3b>(0, 0)[2], 80);
  EXPECT_EQ(nearest.take(100'800'000'000LL, milliseconds(0)), nullptr);  // handed out once
}

}  // namespace
}  // namespace rankslam::replay
