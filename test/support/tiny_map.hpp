#pragma once
// A small, fully populated back-end map (key-frame store, pose graph, loop threshold) for the
// map file's tests and fuzz target: every field set, a retired graph slot, a loop-closure edge.

#include "rankslam/graph/pose_graph.hpp"
#include "rankslam/slam/keyframe_store.hpp"

#include <cstdint>

namespace rankslam::test_support {

/// The capacities tiny maps are made and read with.
struct TinyMap {
  slam::KeyframeStore store{4, 8, 4, 8, 16};
  graph::PoseGraph graph;
  slam::AdaptiveLoopThreshold threshold{12.0, 1.5};

  TinyMap() { (void)graph.configure({4, 32}); }
};

inline Eigen::Isometry3d tiny_pose(int i) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(0.3, 1.0, 0.2).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.25 * i, -0.01 * i, 0.003 * i * i);
  return T;
}

/// Fills `map` (made empty) with three key-frames in slots 0, 1 and 3 and their graph.
inline void fill_tiny_map(TinyMap& map) {
  int nodes[4];
  for (int i = 0; i < 4; ++i) nodes[i] = map.graph.add_node(tiny_pose(i));
  for (int i = 0; i + 1 < 4; ++i) {
    graph::Edge edge;
    edge.from = nodes[i];
    edge.to = nodes[i + 1];
    edge.T_from_to = tiny_pose(i).inverse() * tiny_pose(i + 1);
    edge.information = graph::information_from_matches(40 + i, 0.01, 0.02);
    edge.information(0, 4) = edge.information(4, 0) = 0.5;
    (void)map.graph.add_edge(edge);
  }
  graph::Edge closure;
  closure.from = nodes[0];
  closure.to = nodes[3];
  closure.T_from_to = tiny_pose(0).inverse() * tiny_pose(3);
  closure.information = graph::information_from_matches(25, 0.02, 0.03);
  closure.kind = graph::EdgeKind::kLoopClosure;
  (void)map.graph.add_edge(closure);
  (void)map.graph.remove_node(nodes[2]);  // a retired key-frame: its slot keeps a generation
  map.threshold.add(30, 20);
  map.threshold.add(41, 17);

  std::int64_t sequence = 0;
  for (const int slot : {0, 1, 3}) {
    map.store.occupy(slot);
    slam::StoredKeyframe& keyframe = map.store.slot(slot);
    keyframe.node = nodes[slot];
    keyframe.generation = map.graph.generation(nodes[slot]);
    keyframe.sequence = ++sequence;
    keyframe.stamp_s = 1305031102.175304 + 0.5 * slot;
    keyframe.T_world_cam = tiny_pose(slot);
    keyframe.path_m = 0.25 * slot;
    keyframe.velocity << 0.01 * slot, -0.02, 0.03, 0.1, 0.2 * slot, -0.3;
    keyframe.loop_closures = slot == 3 ? 1 : 0;
    slam::PhotometricFeatures& photometric = keyframe.photometric;
    photometric.clear();
    const int orb = 3 + slot;
    for (int i = 0; i < orb; ++i) {
      photometric.keypoints.emplace_back(10.5F * i, 20.25F + i, 31.0F, 90.0F * i, 0.001F * i, i % 3, -1);
      for (int b = 0; b < 32; ++b) photometric.descriptor_storage.at<unsigned char>(i, b) = static_cast<unsigned char>(7 * i + b + slot);
      photometric.points_cam.emplace_back(0.1F * i, -0.2F, 1.0F + 0.1F * slot);
      photometric.sigma_m.push_back(0.004F * (i + 1));
    }
    photometric.descriptors = photometric.descriptor_storage.rowRange(0, orb);
    photometric.source = slot == 1 ? slam::ImageSource::kInfrared : slam::ImageSource::kColour;
    slam::StoredGeometry& geometric = keyframe.geometric;
    geometric.count = 2;
    for (int i = 0; i < geometric.count; ++i) {
      const auto k = static_cast<std::size_t>(i);
      geometric.points_cam[k] = Eigen::Vector3f(0.5F * i, 0.25F, 2.0F);
      geometric.normals[k] = Eigen::Vector3f(0.0F, 0.0F, -1.0F);
      geometric.sigma_m[k] = 0.01F;
      for (int d = 0; d < geometry::kShotSize; ++d) {
        geometric.codes[k * geometry::kShotSize + static_cast<std::size_t>(d)] = static_cast<std::uint8_t>((d + slot) % 256);
      }
      geometric.scales[k] = 0.001F * static_cast<float>(i + 1);
    }
    geometric.cloud_count = 3;
    for (std::size_t i = 0; i < 3; ++i) {
      geometric.cloud_points[i] = Eigen::Vector3f(0.1F, 0.2F * static_cast<float>(i), 1.5F);
      geometric.cloud_normals[i] = slam::StoredGeometry::encode_normal(Eigen::Vector3f(0.0F, 1.0F, 0.0F));
      geometric.cloud_pixels[i] = Eigen::Vector2f(320.5F, 240.0F + static_cast<float>(i));
      geometric.cloud_curvature[i] = 0.02F;
    }
    geometric.resolution_m = 0.005F;
    geometric.voxel_leaf_m = 0.055F;
    keyframe.point_count = 5;
    for (std::size_t i = 0; i < 5; ++i) {
      keyframe.points[i] = {Eigen::Vector3f(0.01F * static_cast<float>(i), 0.0F, 1.0F), static_cast<std::uint8_t>(i),
                            static_cast<std::uint8_t>(10 * i), 255};
    }
  }
}

}  // namespace rankslam::test_support
