#include "oni_fixture.hpp"

#include <OpenNI.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <thread>
#include <vector>

#include <unistd.h>

namespace rankslam::openni2::test {
namespace {

// OpenNI2's file player drops every frame of a stream whose recording lacks the cropping
// property (PlayerStream::OnNewDataCallback). PS1080 devices record it; the DummyDevice does
// not implement it, so the recorder leaves it out. The recorder does write the supported-modes
// list, which the player ignores, as a general-property record whose name field (26 bytes) and
// 12-byte value have room for "xnCropping" and an XnCropping {enabled = 0} of 12 bytes: that
// record is rewritten in place, so no offset in the file changes.
std::string add_cropping_property(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string modes_name("xnSupportedMapOutputModes", 26);  // with its terminating NUL
  int patched = 0;
  for (std::size_t at = 0;;) {
    const auto found = std::search(bytes.begin() + static_cast<std::ptrdiff_t>(at), bytes.end(), modes_name.begin(), modes_name.end());
    if (found == bytes.end()) break;
    const auto offset = static_cast<std::size_t>(found - bytes.begin());
    std::uint32_t value_size = 0;
    if (offset + modes_name.size() + 4 + 12 > bytes.size()) break;
    std::memcpy(&value_size, bytes.data() + offset + modes_name.size(), 4);
    if (value_size != 12) return path.string() + ": supported-modes record holds " + std::to_string(value_size) + " bytes, 12 expected";
    std::memset(bytes.data() + offset, 0, modes_name.size());
    std::memcpy(bytes.data() + offset, "xnCropping", 10);
    std::memset(bytes.data() + offset + modes_name.size() + 4, 0, 12);
    ++patched;
    at = offset + modes_name.size();
  }
  if (patched != 2) return path.string() + ": " + std::to_string(patched) + " supported-modes records, 2 expected";
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  return out ? std::string() : path.string() + ": cannot rewrite";
}

}  // namespace

hal::Calibration dummy_calibration() {
  hal::Calibration calibration;
  calibration.source = "DummyDevice test calibration";
  calibration.rgb.width = 320;
  calibration.rgb.height = 240;
  calibration.rgb.fx = calibration.rgb.fy = 260.0;
  calibration.rgb.cx = 159.5;
  calibration.rgb.cy = 119.5;
  return calibration;
}

std::filesystem::path fresh_directory(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("rankslam_openni2_" + name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

std::string record_dummy_oni(const std::filesystem::path& path, int milliseconds) {
  if (openni::OpenNI::initialize() != openni::STATUS_OK) return std::string("initialise: ") + openni::OpenNI::getExtendedError();
  openni::Device device;
  if (device.open(kDummyUri) != openni::STATUS_OK) return std::string("open Dummy: ") + openni::OpenNI::getExtendedError();
  openni::VideoStream depth;
  openni::VideoStream color;
  openni::Recorder recorder;
  std::string error;
  if (depth.create(device, openni::SENSOR_DEPTH) != openni::STATUS_OK ||
      color.create(device, openni::SENSOR_COLOR) != openni::STATUS_OK) {
    error = "create streams";
  } else if (recorder.create(path.c_str()) != openni::STATUS_OK || recorder.attach(depth) != openni::STATUS_OK ||
             recorder.attach(color) != openni::STATUS_OK) {
    error = "recorder set-up";
  } else if (depth.start() != openni::STATUS_OK || color.start() != openni::STATUS_OK ||
             recorder.start() != openni::STATUS_OK) {
    error = "start";
  } else {
    std::this_thread::sleep_for(std::chrono::milliseconds(milliseconds));
    recorder.stop();
  }
  depth.stop();
  color.stop();
  // The DummyDevice's producer threads finish their current frame after stop().
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  recorder.destroy();
  depth.destroy();
  color.destroy();
  device.close();
  if (!error.empty()) return error + ": " + openni::OpenNI::getExtendedError();
  return add_cropping_property(path);
}

}  // namespace rankslam::openni2::test
