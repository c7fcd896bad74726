#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

/// Deterministic recording simulator. A recording folder holds (TUM RGB-D layout + extensions):
///   rgb/<stamp>.png      640×480 colour (BGR, 8 bit), with sensor noise and optional motion blur
///   depth/<stamp>.png    640×480 16-bit depth registered to rgb, metres × 5000, 0 = no data
///   rgb.txt depth.txt associations.txt groundtruth.txt (colour optical frame in the world)
///   calibration.yaml     depth_scale, cameras.rgb (+ cameras.fisheye), wheels when can.log exists
///   ir/ + ir.txt         (dark-office) 8-bit IR registered to depth, projector speckle included
///   fisheye/ + fisheye.txt, can.log, slip.txt   (corridor-loop) 10 Hz fisheye, 100 Hz wheel
///                        encoder frames in candump -l format, ground-truth wheel-slip segments
/// Stamps start at 1700000000.000000 and advance 1/30 s per RGB-D frame.
namespace rankslam::sim {

/// What to simulate and where to write it. Every field has a usable default except `scene` and
/// `out_dir`.
struct SimulationOptions {
  /// One of scene_names().
  std::string scene;
  /// Recording folder; created when missing, must be empty when it exists.
  std::filesystem::path out_dir;
  /// RGB-D frames to write; 0 = the scene's default length. Longer runs repeat the motion.
  int frames = 0;
  /// Index of the first frame on the scene's 30 Hz timeline: stamps, motion, noise and wheel
  /// counters continue from there, so a later stretch of a long scene can be written alone.
  int first_frame = 0;
  /// Drives textures, sensor noise, encoder noise and wheel slip; geometry and motion are fixed
  /// per scene so recordings of different seeds share the ground truth.
  std::uint64_t seed = 1;
  /// Drives the textures alone when not 0: recordings of one scene seed and different seeds are
  /// the same place, painted alike, seen through other noise (a later session in a saved map).
  std::uint64_t scene_seed = 0;
  /// Averages sub-exposure renders along the motion (colour, IR and fisheye images; depth is
  /// taken at the frame time). Costs motion_blur_samples times the rendering work.
  bool motion_blur = false;
  /// Renders averaged per blurred image (odd, 3..15).
  int motion_blur_samples = 5;
  /// Exposure time the blur spans, seconds (0 < exposure_s <= 1/30).
  double exposure_s = 0.02;
  /// Kinect depth noise (disparity noise and 1/8 px quantisation), image noise, random depth
  /// drop-outs and encoder tick noise. Off: depth is exact up to the 1/5000 m PNG unit and
  /// images are noise-free (projector shadows, range and grazing-angle limits still apply).
  bool sensor_noise = true;
  /// Occasional short segments in which one wheel's encoder over-counts (listed in slip.txt).
  bool wheel_slip = true;
  /// Render and write images. Off: only groundtruth.txt, calibration.yaml and, for wheeled
  /// scenes, can.log and slip.txt are written (long odometry studies at no rendering cost).
  bool images = true;
  /// Depth sensor range, metres; nearer or farther surfaces read 0.
  double min_depth_m = 0.5;
  double max_depth_m = 4.5;
  /// Worker threads including the calling one; 0 = one per hardware thread. The output does
  /// not depend on it.
  int threads = 0;
  /// zlib level 0..9 for the PNGs with libpng's adaptive row filters; -1 = OpenCV's speed
  /// setting (level 1, one row filter), about twice as fast for the same size.
  int png_compression_level = -1;
};

/// What simulate_recording() did.
struct SimulationSummary {
  int frames_written = 0;
  double seconds = 0.0;            ///< Wall time including set-up and file writing.
  double frames_per_second = 0.0;  ///< frames_written / seconds.
  std::string scene;
};

/// Names accepted by SimulationOptions::scene.
[[nodiscard]] std::vector<std::string> scene_names();

/// One paragraph describing `scene`; empty for an unknown name.
[[nodiscard]] std::string scene_description(const std::string& scene);

/// Writes a recording (TUM RGB-D layout + rankslam extensions) of `options.scene` into
/// `options.out_dir`. Deterministic: the same scene, frames and seed give byte-identical files.
/// Returns an empty string on success, otherwise a message naming what went wrong. `summary`
/// may be null.
[[nodiscard]] std::string simulate_recording(const SimulationOptions& options, SimulationSummary* summary);

/// Whether `dir` holds a recording simulate_recording() wrote of `scene` (its calibration.yaml
/// says so).
[[nodiscard]] bool is_simulated_recording(const std::filesystem::path& dir, const std::string& scene);

}  // namespace rankslam::sim
