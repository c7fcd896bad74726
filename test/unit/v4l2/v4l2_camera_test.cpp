// V4l2Camera on the host: set-up validation and the messages for what is not a camera. Capture
// itself is tested on a real kernel driver (vivid) in test/vm.

#include "rankslam/v4l2/v4l2_camera.hpp"

#include <gtest/gtest.h>

namespace rankslam::v4l2 {
namespace {

using namespace std::chrono_literals;

V4l2Options at(std::string device) {
  V4l2Options options;
  options.device = std::move(device);
  return options;
}

TEST(V4l2Camera, RefusesBadOptionsBeforeOpeningAnything) {
  V4l2Options odd = at("/dev/video0");
  odd.width = 641;
  EXPECT_NE(V4l2Camera(odd).open().find("even width"), std::string::npos);
  V4l2Options few = at("/dev/video0");
  few.buffer_count = 1;
  EXPECT_NE(V4l2Camera(few).open().find("buffer_count 1"), std::string::npos);
  V4l2Options many = at("/dev/video0");
  many.buffer_count = V4l2Camera::kMaxBuffers + 1;
  EXPECT_NE(V4l2Camera(many).open().find("buffer_count"), std::string::npos);
}

TEST(V4l2Camera, NamesAMissingDevice) {
  V4l2Camera camera(at("/dev/rankslam-no-such-video"));
  const std::string error = camera.open();
  EXPECT_NE(error.find("cannot open /dev/rankslam-no-such-video"), std::string::npos) << error;
  EXPECT_FALSE(camera.is_open());
}

TEST(V4l2Camera, RecognisesAFileThatIsNoVideoDevice) {
  V4l2Camera camera(at("/dev/null"));
  const std::string error = camera.open();
  EXPECT_NE(error.find("/dev/null: not a V4L2 device"), std::string::npos) << error;
  EXPECT_FALSE(camera.is_open());
}

TEST(V4l2Camera, AnUnopenedCameraReportsFaultsWithoutBlocking) {
  V4l2Camera camera(at("/dev/null"));
  hal::ImageFrame frame;
  EXPECT_EQ(camera.read(frame, 1000ms), hal::ReadStatus::kFault);
  EXPECT_EQ(camera.counters().faults, 1U);
}

}  // namespace
}  // namespace rankslam::v4l2
