#pragma once

// The map file (docs/map-format.md): what the back-end holds — the stored key-frames, the pose
// graph and the adaptive loop threshold — so that a later run can start in the saved map. The
// point map is not stored: MapBuilder::rebuild makes it again from the key-frames' points.
//
// Layout, little-endian throughout: a header (magic, format version, file size, digests of the
// calibration and of the SLAM configuration, software version, header CRC32), then sections
// (tag, payload length, payload, CRC32 over the three), then the CRC32 of everything before it.
// A reader skips sections with tags it does not know, so a later version can add one (e.g.
// place-recognition vectors) without breaking this one's files.

#include "rankslam/core/fourcc.hpp"
#include "rankslam/graph/pose_graph.hpp"
#include "rankslam/hal/calibration.hpp"
#include "rankslam/slam/config.hpp"
#include "rankslam/slam/keyframe_store.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace rankslam::slam {

/// Format version written; a reader takes versions 1 to this one.
inline constexpr std::uint32_t kMapFormatVersion = 2;
/// Largest map file read: a full default store (256 key-frames of ORB, SHOT and cloud features)
/// takes a few hundred MiB at most.
inline constexpr std::size_t kMaxMapFileBytes = std::size_t{2} << 30U;

/// Section tags: four ASCII characters read as a little-endian word.
enum class MapSection : std::uint32_t {
  kKeyframe = fourcc('K', 'F', 'R', 'M'),       ///< one stored key-frame
  kPoseGraph = fourcc('G', 'R', 'P', 'H'),      ///< nodes (slot generations) and edges
  kLoopThreshold = fourcc('L', 'T', 'H', 'R'),  ///< the adaptive loop threshold's running sums
  // Reserved for a later version: "PLRV", place-recognition vectors (VLAD) per key-frame.
};

/// Digests tying a map to what it was made with.
struct MapDigests {
  /// Of the calibration's numbers (not its source path): another camera's map is refused.
  std::uint32_t calibration = 0;
  /// Of every SLAM and geometry parameter: a changed configuration is reported, not refused.
  std::uint32_t config = 0;
};
[[nodiscard]] std::uint32_t calibration_digest(const hal::Calibration& calibration);
[[nodiscard]] std::uint32_t config_digest(SlamConfig config);

/// The back-end state a map file holds; the objects are the SLAM loop's, sized at its set-up.
struct MapContents {
  KeyframeStore& store;
  graph::PoseGraph& graph;
  AdaptiveLoopThreshold& threshold;
};

/// A copy of the map to write it off the loop's thread (checkpoints): objects sized like the SLAM
/// loop's at set-up (SlamLoop::make_map_snapshot), filled by SlamLoop::snapshot_map without
/// allocating.
struct MapSnapshot {
  KeyframeStore store;
  graph::PoseGraph graph;
  AdaptiveLoopThreshold threshold;
  MapDigests digests;
};

/// What a loaded file said about itself.
struct MapFileInfo {
  std::uint32_t format_version = 0;
  std::string software_version;
  MapDigests digests;
  int keyframes = 0;
  int edges = 0;
};

/// The map file's bytes (appended to `bytes`, which is cleared first).
void encode_map(const KeyframeStore& store, const graph::PoseGraph& graph, const AdaptiveLoopThreshold& threshold,
                const MapDigests& digests, std::vector<unsigned char>& bytes);

/// Reads a map file's bytes into `into` (set-up: no allocation beyond the message of an error).
/// `name` names the file in messages. Throws std::runtime_error "map file <name>: <what is
/// wrong>" for a wrong magic or version, a truncated or corrupt file (with the byte or section),
/// another calibration (`expected.calibration`), or contents over the objects' capacities; the
/// store and graph are then left empty. Never reads past `bytes`.
MapFileInfo decode_map(std::span<const unsigned char> bytes, const std::string& name, const MapDigests& expected,
                       const MapContents& into);

/// Writes the map to `path` atomically (hal::write_file_atomically). Empty on success, else a
/// message naming the file.
[[nodiscard]] std::string save_map_file(const std::filesystem::path& path, const KeyframeStore& store,
                                        const graph::PoseGraph& graph, const AdaptiveLoopThreshold& threshold,
                                        const MapDigests& digests);
/// The same from a snapshot, encoding into `bytes` (kept between calls so that a writer's buffer
/// grows with the map instead of being allocated for every write).
[[nodiscard]] std::string save_map_file(const std::filesystem::path& path, const MapSnapshot& snapshot,
                                        std::vector<unsigned char>& bytes);
/// Writes encoded map bytes to `path` atomically, as save_map_file does.
[[nodiscard]] std::string write_map_bytes(const std::filesystem::path& path, std::span<const unsigned char> bytes);
/// Reads `path` (a regular file) and decodes it as decode_map does; throws std::runtime_error
/// naming the file.
MapFileInfo load_map_file(const std::filesystem::path& path, const MapDigests& expected, const MapContents& into);

}  // namespace rankslam::slam
