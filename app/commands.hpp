#pragma once

#include <sys/resource.h>

#include "rankslam/slam/config.hpp"

#include <cstdint>
#include <optional>
#include <filesystem>
#include <string>
#include <vector>

namespace rankslam::app {

struct ReplayArgs {
  std::filesystem::path recording;  ///< Empty: simulate the built-in default scene first.
  std::filesystem::path out;
  std::string mode;
  std::filesystem::path config;
  double rate = 0.0;
  std::uint32_t max_frames = 0;
  bool quiet = false;
  bool no_wheels = false;  ///< Ignore the recording's can.log: the vision-only run.
  /// Decode the next frames while the loop runs (see replay::ReplayOptions::decode_ahead).
  bool decode_ahead = false;
  /// --frame: "camera", "base" or empty (base when the mounting is known), see OutputFrame.
  std::string frame;
  /// --save-map: where to write the map file at the end (empty: none).
  std::filesystem::path save_map;
  /// --load-map: a map file to start in (empty: a new map).
  std::filesystem::path load_map;
  /// --vocabulary: place-recognition words from `rankslam vocabulary` (empty: the built-in ones).
  std::filesystem::path vocabulary;
};

struct SimulateArgs {
  std::string scene;
  std::filesystem::path out;
  int frames = 0;
  std::uint64_t seed = 1;
  std::uint64_t scene_seed = 0;
  bool motion_blur = false;
};

struct EvalArgs {
  std::filesystem::path ground_truth;
  std::filesystem::path estimate;
  double max_difference_s = 0.02;
  double delta_s = 1.0;
};

struct StereoVoArgs {
  std::filesystem::path dataset;       ///< EuRoC ASL or KITTI odometry sequence directory
  std::filesystem::path out;
  std::string features = "ros2d";      ///< ros2d, sift or orb
  bool no_ba = false;                  ///< frame-to-frame only, no window bundle adjustment
  int max_frames = 0;                  ///< 0 = all pairs
  std::filesystem::path ground_truth;  ///< overrides the dataset's own (TUM, or KITTI poses)
  std::uint64_t seed = 0;              ///< MSSE hypothesis sampler seed; 0 = the built-in one
};

struct RunArgs {
  std::filesystem::path config;
  std::filesystem::path out;
  std::string mode;
  std::string frame;  ///< as ReplayArgs::frame
  /// --can-interface: wins over the file's can.interface (the systemd unit's instance); empty: the file's.
  std::string can_interface;
  /// --load-map: a map file to start in (empty: map.file when it exists, else a new map).
  std::filesystem::path load_map;
  /// --save-map: where checkpoints and the exit write the map (empty: map.file, or nowhere).
  std::filesystem::path save_map;
  std::filesystem::path vocabulary;  ///< as ReplayArgs::vocabulary
};

struct RecordArgs {
  std::filesystem::path out;
  std::filesystem::path config;  ///< Empty: the first OpenNI2 device, no CAN log.
  std::uint32_t frames = 0;      ///< Stop after this many frames (0 = no limit).
  double seconds = 0.0;          ///< Stop after this long (0 = no limit).
};

struct VocabularyArgs {
  std::vector<std::filesystem::path> recordings;
  std::filesystem::path out;
  int words = 64;
  int every = 5;                  ///< every n-th colour frame and wide-angle image
  int max_descriptors = 100000;   ///< k-means over at most this many, evenly spaced
  std::uint64_t seed = 1;
};

[[nodiscard]] int run_record(const RecordArgs& args);
[[nodiscard]] int run_vocabulary(const VocabularyArgs& args);
[[nodiscard]] int run_replay(const ReplayArgs& args);
[[nodiscard]] int run_simulate(const SimulateArgs& args);
[[nodiscard]] int run_eval(const EvalArgs& args);
[[nodiscard]] int run_live(const RunArgs& args);
[[nodiscard]] int run_stereo_vo(const StereoVoArgs& args);

/// The registration `rankslam replay` and `run` use without --mode: fused, the one that holds
/// where either kind of feature alone gets lost (docs/results.md §1).
inline constexpr slam::Mode kDefaultMode = slam::Mode::kFused;

/// The process' peak resident set size so far, MB (getrusage; 0 where unavailable).
[[nodiscard]] inline double peak_rss_mb() {
  rusage usage{};
  if (getrusage(RUSAGE_SELF, &usage) != 0) return 0.0;
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // Linux reports kilobytes
}

/// The vector unit rankslam's own kernels run on: Highway's target ("sse4", "avx2", "avx3",
/// "avx3_dl", "neon"), with "+avx512vnni" where SHOT matching's 8-bit pass runs, or "portable"
/// (RANKSLAM_PORTABLE_KERNELS forces it): report.json's `vector_kernels`.
[[nodiscard]] std::string vector_kernels();

/// The scene `rankslam replay` simulates when given no recording.
inline constexpr const char* kDefaultScene = "office";

}  // namespace rankslam::app
