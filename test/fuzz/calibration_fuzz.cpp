// calibration.yaml as replay reads it: refused with a message or accepted, never a crash or an
// escaped exception; an accepted calibration has finite, positive focal lengths, finite
// principal points and distortion, a positive finite depth scale and a finite mounting.
#include "fuzz_support.hpp"
#include "rankslam/replay/recording.hpp"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

namespace {

using rankslam::fuzz::require;

void require_sane(const rankslam::hal::CameraCalibration& camera) {
  require(camera.width > 0 && camera.height > 0, "an accepted image size is positive");
  require(std::isfinite(camera.fx) && std::isfinite(camera.fy) && camera.fx > 0.0 && camera.fy > 0.0,
          "accepted focal lengths are finite and positive");
  require(std::isfinite(camera.cx) && std::isfinite(camera.cy), "an accepted principal point is finite");
  for (const double k : camera.distortion) require(std::isfinite(k), "accepted distortion is finite");
  require(camera.T_base_cam.matrix().allFinite(), "an accepted mounting is finite");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto path = rankslam::fuzz::scratch_dir() / "calibration.yaml";
  rankslam::fuzz::write_file(path, std::string_view(reinterpret_cast<const char*>(data), size));
  rankslam::hal::Calibration calibration;
  if (!rankslam::replay::load_calibration_yaml(path, calibration).empty()) return 0;
  require(std::isfinite(calibration.depth_scale) && calibration.depth_scale > 0.0,
          "an accepted depth scale is finite and positive");
  require_sane(calibration.rgb);
  if (calibration.fisheye) require_sane(*calibration.fisheye);
  if (calibration.wheels) {
    require(std::isfinite(calibration.wheels->radius_m) && std::isfinite(calibration.wheels->track_width_m),
            "accepted wheel geometry is finite");
  }
  return 0;
}
