#include "rankslam/slam/map_file.hpp"

#include "rankslam/core/fourcc.hpp"
#include "rankslam/core/lie.hpp"
#include "rankslam/hal/atomic_file.hpp"
#include "rankslam/hal/regular_file.hpp"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string_view>
#include <type_traits>
#include <utility>

namespace rankslam::slam {
namespace {

// "\r\n" after the name: a transfer that rewrites line ends breaks the magic, not the sections.
constexpr std::array<unsigned char, 8> kMagic{'R', 'S', 'L', 'M', 'A', 'P', '\r', '\n'};
constexpr std::size_t kMaxSoftwareVersion = 64;
// Tag, payload length, CRC.
constexpr std::size_t kSectionFramingBytes = 4 + 8 + 4;
constexpr std::size_t kTrailerBytes = 4;
constexpr int kDescriptorBytes = 32;
// Largest key-frame sequence number and closure count read: counting on from them cannot overflow.
constexpr std::int32_t kMaxCount = std::int32_t{1} << 30;

std::uint32_t crc32_of(std::span<const unsigned char> bytes) {
  // kMaxMapFileBytes keeps every length within zlib's uInt.
  return static_cast<std::uint32_t>(::crc32(0L, bytes.data(), static_cast<uInt>(bytes.size())));
}

/// A fault found while reading; decode_map names the file in front of it.
struct MapFault : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class ByteWriter {
 public:
  explicit ByteWriter(std::vector<unsigned char>& out) : out_(out) {}

  void u8(std::uint8_t value) { out_.push_back(value); }
  void u16(std::uint16_t value) { little_endian(value, 2); }
  void u32(std::uint32_t value) { little_endian(value, 4); }
  void u64(std::uint64_t value) { little_endian(value, 8); }
  void i32(std::int32_t value) { u32(static_cast<std::uint32_t>(value)); }
  void i64(std::int64_t value) { u64(static_cast<std::uint64_t>(value)); }
  void f32(float value) { u32(std::bit_cast<std::uint32_t>(value)); }
  void f64(double value) { u64(std::bit_cast<std::uint64_t>(value)); }
  void vec3(const Eigen::Vector3f& v) {
    for (int i = 0; i < 3; ++i) f32(v[i]);
  }
  /// Rotation row by row, then translation: the exact doubles, no re-orthonormalisation.
  void pose(const Eigen::Isometry3d& T) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) f64(T.linear()(r, c));
    }
    for (int i = 0; i < 3; ++i) f64(T.translation()[i]);
  }
  void bytes(const unsigned char* data, std::size_t n) { out_.insert(out_.end(), data, data + n); }
  [[nodiscard]] std::size_t position() const { return out_.size(); }
  /// Overwrites `n` bytes at `at` with `value`, little-endian.
  void patch(std::size_t at, std::uint64_t value, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) out_[at + i] = static_cast<unsigned char>(value >> (8U * i));
  }
  /// Appends the CRC32 of the bytes from `from` to here.
  void crc_since(std::size_t from) {
    u32(crc32_of(std::span<const unsigned char>(out_).subspan(from)));
  }

 private:
  void little_endian(std::uint64_t value, std::size_t n) {
    for (std::size_t i = 0; i < n; ++i) out_.push_back(static_cast<unsigned char>(value >> (8U * i)));
  }
  std::vector<unsigned char>& out_;
};

/// Reads little-endian values; every read checks the bytes left first.
class ByteReader {
 public:
  ByteReader(std::span<const unsigned char> bytes, std::string context) : bytes_(bytes), context_(std::move(context)) {}

  std::uint8_t u8() { return static_cast<std::uint8_t>(little_endian(1)); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(little_endian(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(little_endian(4)); }
  std::uint64_t u64() { return little_endian(8); }
  std::int32_t i32() { return static_cast<std::int32_t>(u32()); }
  std::int64_t i64() { return static_cast<std::int64_t>(u64()); }
  float f32() { return std::bit_cast<float>(u32()); }
  double f64() { return std::bit_cast<double>(u64()); }
  Eigen::Vector3f vec3() {
    Eigen::Vector3f v;
    for (int i = 0; i < 3; ++i) v[i] = f32();
    return v;
  }
  Eigen::Isometry3d pose() {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) T.linear()(r, c) = f64();
    }
    for (int i = 0; i < 3; ++i) T.translation()[i] = f64();
    return T;
  }
  /// A count of records of `record_bytes` each, checked against the bytes left and `capacity`.
  std::uint32_t count(std::size_t record_bytes, std::size_t capacity, const char* what, const char* capacity_name) {
    const std::uint32_t n = u32();
    if (n > capacity) {
      fail(std::to_string(n) + " " + what + ", over the capacity of " + std::to_string(capacity) + " (" +
           capacity_name + ")");
    }
    need(static_cast<std::size_t>(n) * record_bytes);
    return n;
  }
  const unsigned char* take(std::size_t n) {
    need(n);
    const unsigned char* data = bytes_.data() + position_;
    position_ += n;
    return data;
  }
  [[nodiscard]] std::size_t position() const { return position_; }
  [[nodiscard]] std::size_t left() const { return bytes_.size() - position_; }
  [[noreturn]] void fail(const std::string& what) const { throw MapFault(context_ + what); }

 private:
  void need(std::size_t n) const {
    if (n <= left()) return;
    // The header is read from the whole file; a section's payload passed its checksum, so it
    // was written short.
    if (context_.empty()) fail("truncated at byte " + std::to_string(bytes_.size()));
    fail("payload ends early (needs " + std::to_string(n) + " bytes at its byte " + std::to_string(position_) + ")");
  }
  std::uint64_t little_endian(std::size_t n) {
    const unsigned char* data = take(n);
    std::uint64_t value = 0;
    for (std::size_t i = 0; i < n; ++i) value |= static_cast<std::uint64_t>(data[i]) << (8U * i);
    return value;
  }

  std::span<const unsigned char> bytes_;
  std::size_t position_ = 0;
  std::string context_;
};

// --- Sections ---------------------------------------------------------------------------------

void write_keyframe(ByteWriter& out, int slot, const StoredKeyframe& keyframe) {
  out.u32(static_cast<std::uint32_t>(slot));
  out.i32(keyframe.node);
  out.u32(keyframe.generation);
  out.i64(keyframe.sequence);
  out.f64(keyframe.stamp_s);
  out.pose(keyframe.T_world_cam);
  out.f64(keyframe.path_m);
  for (int i = 0; i < 6; ++i) out.f64(keyframe.velocity[i]);
  out.i32(keyframe.loop_closures);

  const PhotometricFeatures& photometric = keyframe.photometric;
  out.u8(static_cast<std::uint8_t>(photometric.source));
  out.u32(static_cast<std::uint32_t>(photometric.size()));
  for (std::size_t i = 0; i < photometric.size(); ++i) {
    const cv::KeyPoint& keypoint = photometric.keypoints[i];
    out.f32(keypoint.pt.x);
    out.f32(keypoint.pt.y);
    out.f32(keypoint.size);
    out.f32(keypoint.angle);
    out.f32(keypoint.response);
    out.i32(keypoint.octave);
    out.i32(keypoint.class_id);
    out.bytes(photometric.descriptors.ptr(static_cast<int>(i)), kDescriptorBytes);
    out.vec3(photometric.points_cam[i]);
    out.f32(photometric.sigma_m[i]);
  }

  // What KeyframeStore::copy_features keeps: keypoints, descriptors and the thinned cloud.
  const StoredGeometry& geometric = keyframe.geometric;
  out.f32(geometric.resolution_m);
  out.f32(geometric.voxel_leaf_m);
  out.u32(static_cast<std::uint32_t>(geometric.count));
  for (int i = 0; i < geometric.count; ++i) {
    const auto k = static_cast<std::size_t>(i);
    out.vec3(geometric.points_cam[k]);
    out.vec3(geometric.normals[k]);
    out.f32(geometric.sigma_m[k]);
    out.f32(geometric.scales[k]);
    out.bytes(geometric.codes.data() + k * geometry::kShotSize, geometry::kShotSize);
  }
  out.u32(static_cast<std::uint32_t>(geometric.cloud_count));
  for (int i = 0; i < geometric.cloud_count; ++i) {
    const auto k = static_cast<std::size_t>(i);
    out.vec3(geometric.cloud_points[k]);
    for (const std::int16_t code : geometric.cloud_normals[k]) out.u16(static_cast<std::uint16_t>(code));
    out.f32(geometric.cloud_pixels[k].x());
    out.f32(geometric.cloud_pixels[k].y());
    out.f32(geometric.cloud_curvature[k]);
  }

  out.u32(static_cast<std::uint32_t>(keyframe.point_count));
  for (int i = 0; i < keyframe.point_count; ++i) {
    const KeyframePoint& point = keyframe.points[static_cast<std::size_t>(i)];
    out.vec3(point.point_cam);
    out.u8(point.blue);
    out.u8(point.green);
    out.u8(point.red);
  }
}

constexpr std::size_t kPhotometricRecordBytes = 5 * 4 + 2 * 4 + kDescriptorBytes + 3 * 4 + 4;
// Format version 1 kept each SHOT value and each cloud normal's components as floats.
constexpr std::size_t kGeometricRecordBytes = (3 + 3 + 1 + 1) * 4 + geometry::kShotSize;
constexpr std::size_t kGeometricRecordBytesV1 = (3 + 3 + 1 + geometry::kShotSize) * 4;
constexpr std::size_t kCloudRecordBytes = (3 + 2 + 1) * 4 + 3 * 2;
constexpr std::size_t kCloudRecordBytesV1 = (3 + 3 + 2 + 1) * 4;
constexpr std::size_t kPointRecordBytes = 3 * 4 + 3;

/// The slot a key-frame section is for, without reading the rest.
int keyframe_slot(ByteReader& in, const KeyframeStore& store) {
  const std::uint32_t slot = in.u32();
  if (slot >= static_cast<std::uint32_t>(store.capacity())) {
    in.fail("key-frame slot " + std::to_string(slot) + " is beyond the store's capacity of " +
            std::to_string(store.capacity()) + " (slam.keyframe_capacity)");
  }
  return static_cast<int>(slot);
}

void read_keyframe(ByteReader& in, KeyframeStore& store, const graph::PoseGraph& graph, std::uint32_t version) {
  const int slot = keyframe_slot(in, store);
  if (store.slot(slot).used) in.fail("key-frame slot " + std::to_string(slot) + " appears twice");
  store.occupy(slot);
  StoredKeyframe& keyframe = store.slot(slot);
  keyframe.node = in.i32();
  keyframe.generation = in.u32();
  if (keyframe.node != -1 &&
      (!graph.contains(keyframe.node) || graph.generation(keyframe.node) != keyframe.generation)) {
    in.fail("key-frame slot " + std::to_string(slot) + ": node " + std::to_string(keyframe.node) +
            " (generation " + std::to_string(keyframe.generation) + ") is not in the pose graph");
  }
  keyframe.sequence = in.i64();
  // Bounded so that the loop's sequence counter can go on counting from the largest.
  if (keyframe.sequence < 1 || keyframe.sequence > kMaxCount) {
    in.fail("key-frame slot " + std::to_string(slot) + ": sequence " + std::to_string(keyframe.sequence) +
            " out of range");
  }
  keyframe.stamp_s = in.f64();
  keyframe.T_world_cam = in.pose();
  if (!lie::is_finite_rigid(keyframe.T_world_cam)) {
    in.fail("key-frame slot " + std::to_string(slot) + ": the pose is not a finite rigid transform");
  }
  keyframe.path_m = in.f64();
  for (int i = 0; i < 6; ++i) keyframe.velocity[i] = in.f64();
  keyframe.loop_closures = in.i32();
  if (keyframe.loop_closures < 0 || keyframe.loop_closures > kMaxCount) {
    in.fail("key-frame slot " + std::to_string(slot) + ": loop-closure count out of range");
  }

  PhotometricFeatures& photometric = keyframe.photometric;
  photometric.clear();
  const std::uint8_t source = in.u8();
  if (source > static_cast<std::uint8_t>(ImageSource::kInfrared)) in.fail("unknown image source " + std::to_string(source));
  photometric.source = static_cast<ImageSource>(source);
  const std::size_t photometric_capacity =
      std::min({photometric.keypoints.capacity(), photometric.points_cam.capacity(), photometric.sigma_m.capacity(),
                static_cast<std::size_t>(photometric.descriptor_storage.rows)});
  const std::uint32_t orb = in.count(kPhotometricRecordBytes, photometric_capacity, "ORB features in a key-frame",
                                     "slam.orb_features");
  for (std::uint32_t i = 0; i < orb; ++i) {
    cv::KeyPoint keypoint;
    keypoint.pt.x = in.f32();
    keypoint.pt.y = in.f32();
    keypoint.size = in.f32();
    keypoint.angle = in.f32();
    keypoint.response = in.f32();
    keypoint.octave = in.i32();
    keypoint.class_id = in.i32();
    photometric.keypoints.push_back(keypoint);  // within the capacity reserved at set-up
    std::memcpy(photometric.descriptor_storage.ptr(static_cast<int>(i)), in.take(kDescriptorBytes), kDescriptorBytes);
    photometric.points_cam.push_back(in.vec3());
    photometric.sigma_m.push_back(in.f32());
  }
  photometric.descriptors = photometric.descriptor_storage.rowRange(0, static_cast<int>(orb));

  StoredGeometry& geometric = keyframe.geometric;
  geometric.count = 0;
  geometric.cloud_count = 0;
  geometric.resolution_m = in.f32();
  geometric.voxel_leaf_m = in.f32();
  const std::uint32_t shot =
      in.count(version == 1 ? kGeometricRecordBytesV1 : kGeometricRecordBytes,
               static_cast<std::size_t>(geometric.capacity()), "geometric keypoints in a key-frame", "geometry.max_keypoints");
  for (std::uint32_t i = 0; i < shot; ++i) {
    geometric.points_cam[i] = in.vec3();
    geometric.normals[i] = in.vec3();
    geometric.sigma_m[i] = in.f32();
    std::uint8_t* codes = geometric.codes.data() + static_cast<std::ptrdiff_t>(i) * geometry::kShotSize;
    if (version == 1) {
      std::array<float, geometry::kShotSize> values{};
      for (float& value : values) value = in.f32();
      geometric.scales[i] = StoredGeometry::encode(values.data(), codes);
    } else {
      geometric.scales[i] = in.f32();
      if (!(geometric.scales[i] >= 0.0F) || !std::isfinite(geometric.scales[i])) {
        in.fail("key-frame slot " + std::to_string(slot) + ": SHOT descriptor " + std::to_string(i) + " has scale " +
                std::to_string(geometric.scales[i]));
      }
      std::memcpy(codes, in.take(geometry::kShotSize), geometry::kShotSize);
    }
  }
  geometric.count = static_cast<int>(shot);
  const std::uint32_t cloud = in.count(version == 1 ? kCloudRecordBytesV1 : kCloudRecordBytes,
                                       geometric.cloud_points.size(), "sampled-cloud points in a key-frame",
                                       "the key-frame cloud's capacity");
  for (std::uint32_t i = 0; i < cloud; ++i) {
    geometric.cloud_points[i] = in.vec3();
    if (version == 1) {
      geometric.cloud_normals[i] = StoredGeometry::encode_normal(in.vec3());
    } else {
      for (std::int16_t& code : geometric.cloud_normals[i]) code = static_cast<std::int16_t>(in.u16());
    }
    geometric.cloud_pixels[i].x() = in.f32();
    geometric.cloud_pixels[i].y() = in.f32();
    geometric.cloud_curvature[i] = in.f32();
  }
  geometric.cloud_count = static_cast<int>(cloud);

  const std::uint32_t points =
      in.count(kPointRecordBytes, keyframe.points.size(), "map points in a key-frame", "slam.map_points_per_keyframe");
  for (std::uint32_t i = 0; i < points; ++i) {
    KeyframePoint& point = keyframe.points[i];
    point.point_cam = in.vec3();
    point.blue = in.u8();
    point.green = in.u8();
    point.red = in.u8();
  }
  keyframe.point_count = static_cast<int>(points);
}

void write_graph(ByteWriter& out, const graph::PoseGraph& graph) {
  // Slots up to the last one ever used: their generations tell a later reused slot apart.
  int slots = graph.capacity().max_nodes;
  while (slots > 0 && graph.generation(slots - 1) == 0) --slots;
  out.u32(static_cast<std::uint32_t>(slots));
  out.u64(graph.next_added_order());
  out.i32(graph.fixed_node());
  for (int id = 0; id < slots; ++id) {
    out.u32(graph.generation(id));
    const bool node = graph.contains(id);
    out.u8(node ? 1 : 0);
    if (!node) continue;
    out.u64(graph.added_order(id));
    out.pose(graph.pose(id));
  }
  out.u32(static_cast<std::uint32_t>(graph.edge_count()));
  for (int i = 0; i < graph.edge_count(); ++i) {
    const graph::Edge& edge = graph.edge(i);
    out.i32(edge.from);
    out.i32(edge.to);
    out.u8(static_cast<std::uint8_t>(edge.kind));
    out.pose(edge.T_from_to);
    // The graph keeps the information exactly symmetric: the upper triangle is all of it.
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) out.f64(edge.information(r, c));
    }
  }
}

constexpr std::size_t kPoseBytes = 12 * 8;
constexpr std::size_t kEdgeRecordBytes = 4 + 4 + 1 + kPoseBytes + 21 * 8;

void read_graph(ByteReader& in, graph::PoseGraph& graph) {
  const auto max_nodes = static_cast<std::size_t>(graph.capacity().max_nodes);
  const std::uint32_t slots = in.count(4 + 1, max_nodes, "pose-graph node slots", "slam.keyframe_capacity");
  graph.restore_next_added_order(in.u64());
  const std::int32_t fixed = in.i32();
  for (std::uint32_t id = 0; id < slots; ++id) {
    const std::uint32_t generation = in.u32();
    const std::uint8_t node = in.u8();
    if (node > 1) in.fail("pose-graph slot " + std::to_string(id) + ": bad node flag");
    std::uint64_t order = 0;
    Eigen::Isometry3d T_world_node = Eigen::Isometry3d::Identity();
    if (node != 0) {
      order = in.u64();
      T_world_node = in.pose();
    }
    if (!graph.restore_slot(static_cast<int>(id), generation, node != 0, order, T_world_node)) {
      in.fail("pose-graph node " + std::to_string(id) + ": not a finite rigid pose or out of order");
    }
  }
  if (fixed != -1 && !graph.set_fixed(fixed)) in.fail("the fixed pose-graph node " + std::to_string(fixed) + " is no node");
  const std::uint32_t edges = in.count(kEdgeRecordBytes, static_cast<std::size_t>(graph.capacity().max_edges),
                                       "pose-graph edges", "the graph's edge capacity");
  for (std::uint32_t i = 0; i < edges; ++i) {
    graph::Edge edge;
    edge.from = in.i32();
    edge.to = in.i32();
    const std::uint8_t kind = in.u8();
    if (kind > static_cast<std::uint8_t>(graph::EdgeKind::kPlanar)) in.fail("pose-graph edge " + std::to_string(i) + ": unknown kind");
    edge.kind = static_cast<graph::EdgeKind>(kind);
    edge.T_from_to = in.pose();
    for (int r = 0; r < 6; ++r) {
      for (int c = r; c < 6; ++c) edge.information(r, c) = edge.information(c, r) = in.f64();
    }
    if (!graph.add_edge(edge)) {
      in.fail("pose-graph edge " + std::to_string(i) + " (" + std::to_string(edge.from) + " to " +
              std::to_string(edge.to) + ") is not a valid edge");
    }
  }
}

void write_threshold(ByteWriter& out, const AdaptiveLoopThreshold& threshold) {
  const AdaptiveLoopThreshold::State state = threshold.state();
  out.i32(state.count);
  out.f64(state.sum_p);
  out.f64(state.sum_sq_p);
  out.f64(state.sum_g);
  out.f64(state.sum_sq_g);
}

void read_threshold(ByteReader& in, AdaptiveLoopThreshold& threshold) {
  AdaptiveLoopThreshold::State state;
  state.count = in.i32();
  if (state.count < 0 || state.count > kMaxCount) in.fail("loop-closure count " + std::to_string(state.count) + " out of range");
  state.sum_p = in.f64();
  state.sum_sq_p = in.f64();
  state.sum_g = in.f64();
  state.sum_sq_g = in.f64();
  threshold.restore(state);
}

template <class Write>
void write_section(ByteWriter& out, MapSection tag, Write&& write) {
  const std::size_t start = out.position();
  out.u32(static_cast<std::uint32_t>(tag));
  out.u64(0);
  write(out);
  out.patch(start + 4, out.position() - start - 12, 8);
  out.crc_since(start);
}

/// A verified section: its index, tag, and payload's place in the file.
struct SectionView {
  int index = 0;
  std::uint32_t tag = 0;
  std::size_t offset = 0;
  std::span<const unsigned char> payload;
};

/// Calls visit(section) for each section between the header and the trailer, checking framing
/// and (when `verify`: on the first pass) CRC first.
template <class Visit>
void for_each_section(std::span<const unsigned char> body, std::size_t body_offset, bool verify, Visit&& visit) {
  std::size_t at = 0;
  for (int index = 1; at < body.size(); ++index) {
    const std::size_t offset = body_offset + at;
    const std::string where = "section " + std::to_string(index) + " at byte " + std::to_string(offset);
    if (body.size() - at < kSectionFramingBytes) throw MapFault("corrupt " + where + ": shorter than its framing");
    ByteReader framing(body.subspan(at, 12), {});
    const std::uint32_t tag = framing.u32();
    const std::uint64_t length = framing.u64();
    if (length > body.size() - at - kSectionFramingBytes) {
      throw MapFault("corrupt " + where + ": its length " + std::to_string(length) + " runs past the end");
    }
    const auto payload_length = static_cast<std::size_t>(length);
    ByteReader crc(body.subspan(at + 12 + payload_length, 4), {});
    if (verify && crc.u32() != crc32_of(body.subspan(at, 12 + payload_length))) {
      throw MapFault("checksum mismatch in " + where + " (" + fourcc_to_string(tag) + ")");
    }
    visit(SectionView{index, tag, offset, body.subspan(at + 12, payload_length)});
    at += kSectionFramingBytes + payload_length;
  }
}

void clear(const MapContents& map) {
  for (int i = 0; i < map.store.capacity(); ++i) map.store.release(i);
  (void)map.graph.configure(map.graph.capacity());
  map.threshold.restore({});
}

template <class Field>
void digest_value(ByteWriter& out, const Field& field) {
  if constexpr (std::is_enum_v<Field>) {
    out.i64(static_cast<std::int64_t>(field));
  } else {
    static_assert(std::is_arithmetic_v<Field>, "a parameter the digest does not know how to encode");
    out.f64(static_cast<double>(field));
  }
}

void digest_camera(ByteWriter& out, const hal::CameraCalibration& camera) {
  digest_value(out, camera.model);
  for (const double value : {static_cast<double>(camera.width), static_cast<double>(camera.height), camera.fx, camera.fy,
                             camera.cx, camera.cy}) {
    out.f64(value);
  }
  for (const double k : camera.distortion) out.f64(k);
  out.pose(camera.T_base_cam);
  out.u8(camera.T_base_cam_given ? 1 : 0);
}

}  // namespace

std::uint32_t calibration_digest(const hal::Calibration& calibration) {
  std::vector<unsigned char> bytes;
  ByteWriter out(bytes);
  out.f64(calibration.depth_scale);
  out.f64(calibration.depth_noise_per_m);
  digest_camera(out, calibration.rgb);
  out.u8(calibration.fisheye.has_value() ? 1 : 0);
  if (calibration.fisheye) digest_camera(out, *calibration.fisheye);
  out.u8(calibration.wheels.has_value() ? 1 : 0);
  if (calibration.wheels) {
    out.f64(calibration.wheels->radius_m);
    out.f64(calibration.wheels->track_width_m);
    out.i32(calibration.wheels->ticks_per_revolution);
    out.u32(calibration.wheels->can_id);
  }
  return crc32_of(bytes);
}

std::uint32_t config_digest(SlamConfig config) {
  std::vector<unsigned char> bytes;
  ByteWriter out(bytes);
  const auto add = [&out](const auto& name, const auto& field, auto&&...) {
    const std::string_view text(name);
    out.bytes(reinterpret_cast<const unsigned char*>(text.data()), text.size());
    digest_value(out, field);
  };
  digest_value(out, config.mode);
  config.visit_parameters(add);
  config.geometry.visit_parameters(add);
  return crc32_of(bytes);
}

void encode_map(const KeyframeStore& store, const graph::PoseGraph& graph, const AdaptiveLoopThreshold& threshold,
                const MapDigests& digests, std::vector<unsigned char>& bytes) {
  bytes.clear();
  ByteWriter out(bytes);
  out.bytes(kMagic.data(), kMagic.size());
  out.u32(kMapFormatVersion);
  const std::size_t size_at = out.position();
  out.u64(0);
  out.u32(digests.calibration);
  out.u32(digests.config);
  const std::string_view software = RANKSLAM_VERSION;
  const std::size_t software_length = std::min(software.size(), kMaxSoftwareVersion);
  out.u16(static_cast<std::uint16_t>(software_length));
  out.bytes(reinterpret_cast<const unsigned char*>(software.data()), software_length);
  const std::size_t header_crc_at = out.position();
  out.u32(0);

  std::size_t estimate = 1024;
  for (int i = 0; i < store.capacity(); ++i) {
    const StoredKeyframe& keyframe = store.slot(i);
    if (!keyframe.used) continue;
    estimate += 512 + keyframe.photometric.size() * kPhotometricRecordBytes +
                static_cast<std::size_t>(keyframe.geometric.count) * kGeometricRecordBytes +
                static_cast<std::size_t>(keyframe.geometric.cloud_count) * kCloudRecordBytes +
                static_cast<std::size_t>(keyframe.point_count) * kPointRecordBytes;
  }
  bytes.reserve(estimate + static_cast<std::size_t>(graph.edge_count()) * kEdgeRecordBytes +
                static_cast<std::size_t>(graph.capacity().max_nodes) * (13 + kPoseBytes));
  write_section(out, MapSection::kPoseGraph, [&](ByteWriter& w) { write_graph(w, graph); });
  write_section(out, MapSection::kLoopThreshold, [&](ByteWriter& w) { write_threshold(w, threshold); });
  for (int i = 0; i < store.capacity(); ++i) {
    if (!store.slot(i).used) continue;
    write_section(out, MapSection::kKeyframe, [&](ByteWriter& w) { write_keyframe(w, i, store.slot(i)); });
  }
  // The header's CRC covers the file size, known only now.
  out.patch(size_at, out.position() + kTrailerBytes, 8);
  out.patch(header_crc_at, crc32_of(std::span<const unsigned char>(bytes).first(header_crc_at)), 4);
  out.crc_since(0);
}

MapFileInfo decode_map(std::span<const unsigned char> bytes, const std::string& name, const MapDigests& expected,
                       const MapContents& into) {
  const std::string prefix = "map file " + name + ": ";
  try {
    if (bytes.empty()) throw MapFault("empty file");
    if (!std::equal(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(std::min(bytes.size(), kMagic.size())),
                    kMagic.begin())) {
      throw MapFault("not a rankslam map file (wrong magic)");
    }
    ByteReader header(bytes, {});
    header.take(kMagic.size());
    MapFileInfo info;
    info.format_version = header.u32();
    if (info.format_version < 1 || info.format_version > kMapFormatVersion) {
      throw MapFault("unsupported format version " + std::to_string(info.format_version) + " (this build reads 1 to " +
                     std::to_string(kMapFormatVersion) + ")");
    }
    const std::uint64_t file_size = header.u64();
    info.digests.calibration = header.u32();
    info.digests.config = header.u32();
    const std::uint16_t software_length = header.u16();
    if (software_length > kMaxSoftwareVersion) {
      throw MapFault("corrupt header: software version of " + std::to_string(software_length) + " bytes");
    }
    const unsigned char* software = header.take(software_length);
    const std::size_t header_bytes = header.position();
    if (header.u32() != crc32_of(bytes.first(header_bytes))) throw MapFault("corrupt header: header checksum mismatch");
    info.software_version.assign(reinterpret_cast<const char*>(software), software_length);
    if (file_size > bytes.size()) {
      throw MapFault("truncated at byte " + std::to_string(bytes.size()) + " of " + std::to_string(file_size));
    }
    if (file_size < header.position() + kTrailerBytes) throw MapFault("corrupt header: file size " + std::to_string(file_size));
    if (file_size < bytes.size()) {
      throw MapFault(std::to_string(bytes.size() - file_size) + " bytes after the end at byte " + std::to_string(file_size));
    }
    const std::size_t trailer_at = bytes.size() - kTrailerBytes;
    ByteReader trailer(bytes.subspan(trailer_at), {});
    const std::span<const unsigned char> body = bytes.subspan(header.position(), trailer_at - header.position());

    // Framing and checksums of everything before a byte is used.
    int keyframes = 0;
    int graphs = 0;
    int thresholds = 0;
    for_each_section(body, header.position(), true, [&](const SectionView& section) {
      keyframes += section.tag == static_cast<std::uint32_t>(MapSection::kKeyframe) ? 1 : 0;
      graphs += section.tag == static_cast<std::uint32_t>(MapSection::kPoseGraph) ? 1 : 0;
      thresholds += section.tag == static_cast<std::uint32_t>(MapSection::kLoopThreshold) ? 1 : 0;
    });
    if (trailer.u32() != crc32_of(bytes.first(trailer_at))) throw MapFault("file checksum mismatch");
    if (graphs != 1 || thresholds != 1) {
      throw MapFault("corrupt: " + std::to_string(graphs) + " pose-graph and " + std::to_string(thresholds) +
                     " loop-threshold sections, one of each expected");
    }
    if (info.digests.calibration != expected.calibration) {
      throw MapFault("made with another calibration (digest " + std::to_string(info.digests.calibration) +
                     ", this camera's " + std::to_string(expected.calibration) + ")");
    }
    if (keyframes > into.store.capacity()) {
      throw MapFault("holds " + std::to_string(keyframes) + " key-frames, more than the store's capacity of " +
                     std::to_string(into.store.capacity()) + " (slam.keyframe_capacity)");
    }

    clear(into);
    try {
      const auto context = [](const SectionView& section) {
        return "section " + std::to_string(section.index) + " (" + fourcc_to_string(section.tag) + " at byte " +
               std::to_string(section.offset) + "): ";
      };
      // The graph first: key-frames name its nodes.
      for_each_section(body, header.position(), false, [&](const SectionView& section) {
        ByteReader in(section.payload, context(section));
        if (section.tag == static_cast<std::uint32_t>(MapSection::kPoseGraph)) {
          read_graph(in, into.graph);
        } else if (section.tag == static_cast<std::uint32_t>(MapSection::kLoopThreshold)) {
          read_threshold(in, into.threshold);
        } else {
          return;
        }
        if (in.left() != 0) in.fail(std::to_string(in.left()) + " bytes left over");
      });
      for_each_section(body, header.position(), false, [&](const SectionView& section) {
        if (section.tag != static_cast<std::uint32_t>(MapSection::kKeyframe)) return;
        ByteReader in(section.payload, context(section));
        read_keyframe(in, into.store, into.graph, info.format_version);
        if (in.left() != 0) in.fail(std::to_string(in.left()) + " bytes left over");
      });
    } catch (...) {
      clear(into);
      throw;
    }
    info.keyframes = keyframes;
    info.edges = into.graph.edge_count();
    return info;
  } catch (const MapFault& fault) {
    throw std::runtime_error(prefix + fault.what());
  }
}

std::string write_map_bytes(const std::filesystem::path& path, std::span<const unsigned char> bytes) {
  return hal::write_file_atomically(path, std::span<const char>(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

std::string save_map_file(const std::filesystem::path& path, const KeyframeStore& store, const graph::PoseGraph& graph,
                          const AdaptiveLoopThreshold& threshold, const MapDigests& digests) {
  std::vector<unsigned char> bytes;
  encode_map(store, graph, threshold, digests, bytes);
  return write_map_bytes(path, bytes);
}

std::string save_map_file(const std::filesystem::path& path, const MapSnapshot& snapshot,
                          std::vector<unsigned char>& bytes) {
  encode_map(snapshot.store, snapshot.graph, snapshot.threshold, snapshot.digests, bytes);
  return write_map_bytes(path, bytes);
}

MapFileInfo load_map_file(const std::filesystem::path& path, const MapDigests& expected, const MapContents& into) {
  std::vector<unsigned char> bytes;
  if (std::string error = hal::read_regular_file(path, kMaxMapFileBytes, bytes); !error.empty()) {
    throw std::runtime_error("map file: " + error);
  }
  return decode_map(bytes, path.string(), expected, into);
}

}  // namespace rankslam::slam
