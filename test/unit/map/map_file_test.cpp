// The map file (slam/map_file.hpp): a tiny, fully populated map round-trips field by field and
// byte for byte; every truncation, flipped byte, wrong version or magic, missing or odd path,
// other calibration and over-capacity content is refused with a message naming the file; a
// failed write leaves the previous file.
#include "rankslam/slam/map_file.hpp"
#include "tiny_map.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

namespace rankslam::slam {
namespace {

namespace fs = std::filesystem;
using test_support::fill_tiny_map;
using test_support::TinyMap;

constexpr MapDigests kDigests{0x1234ABCDU, 0x00C0FFEEU};
constexpr std::size_t kMagicBytes = 8;
constexpr std::size_t kVersionEnd = 12;

std::vector<unsigned char> tiny_map_bytes() {
  TinyMap map;
  fill_tiny_map(map);
  std::vector<unsigned char> bytes;
  encode_map(map.store, map.graph, map.threshold, kDigests, bytes);
  return bytes;
}

/// The header's length: the fixed fields, the software version, the CRC.
std::size_t header_bytes(const std::vector<unsigned char>& bytes) {
  const std::size_t software = bytes[28] | (static_cast<std::size_t>(bytes[29]) << 8U);
  return 30 + software + 4;
}

/// decode_map's message for `bytes`, or "" when it is accepted.
std::string refusal(std::span<const unsigned char> bytes, const MapDigests& expected = kDigests) {
  TinyMap into;
  try {
    (void)decode_map(bytes, "tiny.map", expected, {into.store, into.graph, into.threshold});
  } catch (const std::runtime_error& error) {
    EXPECT_EQ(into.store.size(), 0) << "a refused map leaves the store empty";
    EXPECT_EQ(into.graph.node_count(), 0) << "a refused map leaves the graph empty";
    return error.what();
  }
  return {};
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::vector<unsigned char> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void expect_same_isometry(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  EXPECT_EQ(a.matrix(), b.matrix());
}

TEST(MapFile, TinyMapRoundTripsFieldByFieldAndByteForByte) {
  TinyMap map;
  fill_tiny_map(map);
  std::vector<unsigned char> bytes;
  encode_map(map.store, map.graph, map.threshold, kDigests, bytes);

  TinyMap loaded;
  const MapFileInfo info = decode_map(bytes, "tiny.map", kDigests, {loaded.store, loaded.graph, loaded.threshold});
  EXPECT_EQ(info.format_version, kMapFormatVersion);
  EXPECT_EQ(info.keyframes, 3);
  EXPECT_EQ(info.digests.config, kDigests.config);
  EXPECT_FALSE(info.software_version.empty());

  ASSERT_EQ(loaded.store.size(), map.store.size());
  for (int slot = 0; slot < map.store.capacity(); ++slot) {
    const StoredKeyframe& a = map.store.slot(slot);
    const StoredKeyframe& b = loaded.store.slot(slot);
    ASSERT_EQ(a.used, b.used) << "slot " << slot;
    if (!a.used) continue;
    EXPECT_EQ(a.node, b.node);
    EXPECT_EQ(a.generation, b.generation);
    EXPECT_EQ(a.sequence, b.sequence);
    EXPECT_EQ(a.stamp_s, b.stamp_s);
    expect_same_isometry(a.T_world_cam, b.T_world_cam);
    EXPECT_EQ(a.path_m, b.path_m);
    EXPECT_EQ(a.velocity, b.velocity);
    EXPECT_EQ(a.loop_closures, b.loop_closures);
    ASSERT_EQ(a.photometric.size(), b.photometric.size());
    EXPECT_EQ(a.photometric.source, b.photometric.source);
    for (std::size_t i = 0; i < a.photometric.size(); ++i) {
      const cv::KeyPoint& ka = a.photometric.keypoints[i];
      const cv::KeyPoint& kb = b.photometric.keypoints[i];
      EXPECT_TRUE(ka.pt == kb.pt && ka.size == kb.size && ka.angle == kb.angle && ka.response == kb.response &&
                  ka.octave == kb.octave && ka.class_id == kb.class_id);
      EXPECT_EQ(a.photometric.points_cam[i], b.photometric.points_cam[i]);
      EXPECT_EQ(a.photometric.sigma_m[i], b.photometric.sigma_m[i]);
    }
    EXPECT_EQ(cv::norm(a.photometric.descriptors, b.photometric.descriptors, cv::NORM_HAMMING), 0.0);
    ASSERT_EQ(a.geometric.count, b.geometric.count);
    ASSERT_EQ(a.geometric.cloud_count, b.geometric.cloud_count);
    EXPECT_EQ(a.geometric.codes, b.geometric.codes);
    EXPECT_EQ(a.geometric.scales, b.geometric.scales);
    EXPECT_EQ(a.geometric.points_cam, b.geometric.points_cam);
    EXPECT_EQ(a.geometric.cloud_pixels, b.geometric.cloud_pixels);
    EXPECT_EQ(a.geometric.voxel_leaf_m, b.geometric.voxel_leaf_m);
    ASSERT_EQ(a.point_count, b.point_count);
    for (int p = 0; p < a.point_count; ++p) {
      const auto k = static_cast<std::size_t>(p);
      EXPECT_EQ(a.points[k].point_cam, b.points[k].point_cam);
      EXPECT_TRUE(a.points[k].blue == b.points[k].blue && a.points[k].green == b.points[k].green &&
                  a.points[k].red == b.points[k].red);
    }
  }

  ASSERT_EQ(loaded.graph.node_count(), map.graph.node_count());
  ASSERT_EQ(loaded.graph.edge_count(), map.graph.edge_count());
  EXPECT_EQ(loaded.graph.fixed_node(), map.graph.fixed_node());
  EXPECT_EQ(loaded.graph.next_added_order(), map.graph.next_added_order());
  for (int id = 0; id < map.graph.capacity().max_nodes; ++id) {
    EXPECT_EQ(loaded.graph.contains(id), map.graph.contains(id));
    EXPECT_EQ(loaded.graph.generation(id), map.graph.generation(id));
    EXPECT_EQ(loaded.graph.added_order(id), map.graph.added_order(id));
    expect_same_isometry(loaded.graph.pose(id), map.graph.pose(id));
  }
  for (int i = 0; i < map.graph.edge_count(); ++i) {
    const graph::Edge& a = map.graph.edge(i);
    const graph::Edge& b = loaded.graph.edge(i);
    EXPECT_TRUE(a.from == b.from && a.to == b.to && a.kind == b.kind);
    expect_same_isometry(a.T_from_to, b.T_from_to);
    EXPECT_EQ(a.information, b.information);
  }
  EXPECT_EQ(loaded.graph.cost(), map.graph.cost());
  EXPECT_EQ(loaded.threshold.count(), map.threshold.count());
  EXPECT_EQ(loaded.threshold.value(), map.threshold.value());

  std::vector<unsigned char> again;
  encode_map(loaded.store, loaded.graph, loaded.threshold, kDigests, again);
  EXPECT_EQ(again, bytes);
}

// The checkpoint's copy: a store copied into one of the same sizes encodes to the same bytes,
// after a first copy, a retired key-frame, a new one in its slot and moved poses too.
TEST(MapFile, AStoreCopiedIntoOneOfTheSameSizesEncodesTheSame) {
  TinyMap map;
  fill_tiny_map(map);
  TinyMap copy;
  std::vector<unsigned char> original;
  std::vector<unsigned char> copied;
  ASSERT_TRUE(copy.store.copy_from(map.store));
  ASSERT_TRUE(copy.graph.copy_from(map.graph));
  encode_map(map.store, map.graph, map.threshold, kDigests, original);
  encode_map(copy.store, copy.graph, map.threshold, kDigests, copied);
  EXPECT_TRUE(original == copied);

  // Slot 1 retired and reused by a new key-frame with other features; slot 3 moved.
  StoredKeyframe& reused = map.store.slot(1);
  map.store.release(1);
  map.store.occupy(1);
  reused.sequence = 10;
  reused.node = map.store.slot(0).node;
  reused.photometric.keypoints.resize(1);
  reused.photometric.points_cam.resize(1);
  reused.photometric.sigma_m.resize(1);
  reused.photometric.descriptors = reused.photometric.descriptor_storage.rowRange(0, 1);
  reused.point_count = 1;
  map.store.slot(3).T_world_cam = test_support::tiny_pose(7);
  map.store.release(0);
  ASSERT_TRUE(copy.store.copy_from(map.store));
  encode_map(map.store, map.graph, map.threshold, kDigests, original);
  encode_map(copy.store, copy.graph, map.threshold, kDigests, copied);
  EXPECT_TRUE(original == copied) << original.size() << " bytes against " << copied.size();
  EXPECT_EQ(copy.store.size(), map.store.size());

  slam::KeyframeStore other_sizes{5, 8, 4, 8, 16};
  EXPECT_FALSE(other_sizes.copy_from(map.store));
}

TEST(MapFile, RefusesTruncationAtEveryOffset) {
  const std::vector<unsigned char> bytes = tiny_map_bytes();
  ASSERT_EQ(refusal(bytes), "");
  EXPECT_EQ(refusal(std::span(bytes).first(0)), "map file tiny.map: empty file");
  for (std::size_t size = 1; size < bytes.size(); ++size) {
    const std::string message = refusal(std::span(bytes).first(size));
    ASSERT_NE(message.find("map file tiny.map: truncated at byte " + std::to_string(size)), std::string::npos)
        << "cut at " << size << ": " << message;
  }
}

TEST(MapFile, RefusesEveryFlippedByteOfTheHeaderAndOfTheRest) {
  const std::vector<unsigned char> bytes = tiny_map_bytes();
  const std::size_t header = header_bytes(bytes);
  for (std::size_t at = 0; at < bytes.size(); ++at) {
    std::vector<unsigned char> flipped = bytes;
    flipped[at] ^= 0x5AU;
    const std::string message = refusal(flipped);
    const char* expected = at < kMagicBytes      ? "wrong magic"
                           : at < kVersionEnd    ? "unsupported format version"
                           : at < header         ? "corrupt header"
                           : at + 4 >= bytes.size() ? "file checksum mismatch"
                                                    : "";
    if (expected[0] != '\0') {
      EXPECT_NE(message.find(expected), std::string::npos) << "byte " << at << ": " << message;
    } else {
      // A section's framing or payload: its checksum, or a length that runs past the end.
      EXPECT_TRUE(message.find("checksum mismatch in section") != std::string::npos ||
                  message.find("corrupt section") != std::string::npos)
          << "byte " << at << ": " << message;
    }
  }
}

TEST(MapFile, NamesAWrongVersionAndAWrongMagic) {
  std::vector<unsigned char> bytes = tiny_map_bytes();
  bytes[8] = 3;
  EXPECT_EQ(refusal(bytes), "map file tiny.map: unsupported format version 3 (this build reads 1 to 2)");
  const std::string text = "P5\n640 480\n255\n";
  EXPECT_EQ(refusal(std::span(reinterpret_cast<const unsigned char*>(text.data()), text.size())),
            "map file tiny.map: not a rankslam map file (wrong magic)");
}

TEST(MapFile, RefusesAnotherCalibrationButNotAnotherConfiguration) {
  const std::vector<unsigned char> bytes = tiny_map_bytes();
  EXPECT_NE(refusal(bytes, {kDigests.calibration + 1, kDigests.config}).find("made with another calibration"),
            std::string::npos);
  EXPECT_EQ(refusal(bytes, {kDigests.calibration, kDigests.config + 1}), "");
}

TEST(MapFile, RefusesMoreKeyframesOrFeaturesThanTheSlotsHold) {
  const std::vector<unsigned char> bytes = tiny_map_bytes();
  const auto refusal_into = [&bytes](KeyframeStore store) {
    TinyMap map;
    try {
      (void)decode_map(bytes, "tiny.map", kDigests, {store, map.graph, map.threshold});
    } catch (const std::runtime_error& error) {
      EXPECT_EQ(store.size(), 0);
      return std::string(error.what());
    }
    return std::string();
  };
  EXPECT_NE(refusal_into(KeyframeStore(2, 8, 4, 8, 16)).find("holds 3 key-frames, more than the store's capacity of 2"),
            std::string::npos);
  EXPECT_NE(refusal_into(KeyframeStore(3, 8, 4, 8, 16)).find("key-frame slot 3 is beyond the store's capacity of 3"),
            std::string::npos);
  EXPECT_NE(refusal_into(KeyframeStore(4, 4, 4, 8, 16)).find("6 ORB features in a key-frame, over the capacity of 4"),
            std::string::npos);
  EXPECT_NE(refusal_into(KeyframeStore(4, 8, 1, 8, 16)).find("2 geometric keypoints in a key-frame, over the capacity of 1"),
            std::string::npos);
  EXPECT_NE(refusal_into(KeyframeStore(4, 8, 4, 8, 4)).find("5 map points in a key-frame, over the capacity of 4"),
            std::string::npos);
}

TEST(MapFile, LoadNamesAMissingFileADirectoryAndAnEmptyFile) {
  const fs::path dir = fresh_dir("rankslam_map_file_paths");
  const auto load_refusal = [](const fs::path& path) {
    TinyMap map;
    try {
      (void)load_map_file(path, kDigests, {map.store, map.graph, map.threshold});
    } catch (const std::runtime_error& error) {
      return std::string(error.what());
    }
    return std::string();
  };
  const std::string missing = load_refusal(dir / "missing.map");
  EXPECT_NE(missing.find((dir / "missing.map").string()), std::string::npos) << missing;
  const std::string directory = load_refusal(dir);
  EXPECT_NE(directory.find(dir.string()), std::string::npos) << directory;
  EXPECT_NE(directory.find("map file"), std::string::npos) << directory;
  std::ofstream(dir / "empty.map").close();
  EXPECT_EQ(load_refusal(dir / "empty.map"), "map file " + (dir / "empty.map").string() + ": empty file");
  fs::remove_all(dir);
}

TEST(MapFile, AFailedWriteLeavesThePreviousFileWhole) {
  const fs::path dir = fresh_dir("rankslam_map_file_atomic");
  const fs::path path = dir / "office.map";
  TinyMap small;
  ASSERT_EQ(save_map_file(path, small.store, small.graph, small.threshold, kDigests), "");
  const std::vector<unsigned char> previous = read_bytes(path);
  TinyMap full;
  fill_tiny_map(full);

  // A file-size limit below the new map's size makes the write fail half-way (EFBIG).
  rlimit saved{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &saved), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit limited = saved;
  limited.rlim_cur = 1024;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limited), 0);
  const std::string error = save_map_file(path, full.store, full.graph, full.threshold, kDigests);
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &saved), 0);
  std::signal(SIGXFSZ, old_handler);

  EXPECT_NE(error.find(path.string()), std::string::npos) << error;
  EXPECT_EQ(read_bytes(path), previous);
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++entries;
  EXPECT_EQ(entries, 1) << "no temporary file is left";
  ASSERT_EQ(save_map_file(path, full.store, full.graph, full.threshold, kDigests), "");
  EXPECT_EQ(refusal(read_bytes(path)), "");
  fs::remove_all(dir);
}

TEST(MapFile, DigestsFollowTheNumbersNotTheCalibrationsSource) {
  hal::Calibration calibration;
  calibration.rgb.fx = 525.0;
  const std::uint32_t digest = calibration_digest(calibration);
  calibration.source = "elsewhere/calibration.yaml";
  EXPECT_EQ(calibration_digest(calibration), digest);
  calibration.rgb.fx = 525.5;
  EXPECT_NE(calibration_digest(calibration), digest);
  SlamConfig config;
  const std::uint32_t config_before = config_digest(config);
  config.loop.search_radius_m += 0.5;
  EXPECT_NE(config_digest(config), config_before);
}

// A map of format version 1 (SHOT values as floats; the fuzz target's first seed, written before
// version 2) loads, its values encoded as the store keeps them, and saves as version 2.
TEST(MapFile, AVersionOneMapLoadsWithItsShotValuesEncoded) {
  const fs::path seed = fs::path(RANKSLAM_SOURCE_DIR) / "test/fuzz/corpus/map_file/tiny.map";
  const std::vector<unsigned char> bytes = read_bytes(seed);
  ASSERT_FALSE(bytes.empty()) << seed;
  TinyMap loaded;
  const MapFileInfo info = decode_map(bytes, "tiny.map", kDigests, {loaded.store, loaded.graph, loaded.threshold});
  EXPECT_EQ(info.format_version, 1U);
  ASSERT_EQ(loaded.store.size(), 3);
  // Version 1's tiny map held 0.001 × d in every descriptor's value d.
  TinyMap expected;
  fill_tiny_map(expected);
  std::vector<float> values(geometry::kShotSize);
  for (const int slot : {0, 1, 3}) {
    const StoredGeometry& geometric = loaded.store.slot(slot).geometric;
    ASSERT_EQ(geometric.count, 2) << "slot " << slot;
    EXPECT_EQ(geometric.points_cam, expected.store.slot(slot).geometric.points_cam);
    for (int k = 0; k < geometric.count; ++k) {
      const float scale = geometric.scales[static_cast<std::size_t>(k)];
      StoredGeometry::decode(geometric.codes.data() + static_cast<std::ptrdiff_t>(k) * geometry::kShotSize, scale,
                             values.data());
      for (int d = 0; d < geometry::kShotSize; ++d) {
        ASSERT_NEAR(values[static_cast<std::size_t>(d)], 0.001F * static_cast<float>(d), 0.5F * scale * 1.0001F);
      }
    }
  }
  std::vector<unsigned char> again;
  encode_map(loaded.store, loaded.graph, loaded.threshold, kDigests, again);
  TinyMap reloaded;
  EXPECT_EQ(decode_map(again, "tiny.map", kDigests, {reloaded.store, reloaded.graph, reloaded.threshold}).format_version,
            kMapFormatVersion);
  EXPECT_EQ(reloaded.store.slot(3).geometric.codes, loaded.store.slot(3).geometric.codes);
  EXPECT_LT(again.size(), bytes.size());
}

// The fuzz target's seed (test/fuzz/corpus/map_file): RANKSLAM_WRITE_MAP_SEED=<file> writes it.
TEST(MapFile, WritesTheFuzzSeedWhenAsked) {
  const char* path = std::getenv("RANKSLAM_WRITE_MAP_SEED");
  if (path == nullptr) GTEST_SKIP() << "RANKSLAM_WRITE_MAP_SEED not set";
  TinyMap map;
  fill_tiny_map(map);
  ASSERT_EQ(save_map_file(path, map.store, map.graph, map.threshold, kDigests), "");
}

}  // namespace
}  // namespace rankslam::slam
