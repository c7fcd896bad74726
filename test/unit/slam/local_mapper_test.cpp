// Local mapping on a synthetic key-frame store: key-frames along a path see a cloud of landmarks
// (each with its own descriptor, positions with the depth camera's noise), and their registration
// edges are off the truth by a few millimetres. The mapper must match the key-frames' features
// into landmarks, refine each edge once (when it is the oldest of a full window, and the rest at
// the end of the run) and bring it closer to the truth; an edge whose key-frame left the graph
// meanwhile is left alone.

#include "rankslam/slam/local_mapper.hpp"
#include "wall_sequence.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

namespace rankslam::slam {
namespace {

constexpr int kKeyframes = 7;
constexpr int kLandmarks = 800;
constexpr int kFeatures = 1000;

Eigen::Isometry3d pose(double yaw_rad, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY()).toRotationMatrix();
  T.translation() = t;
  return T;
}

double edge_error_m(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  return (truth.inverse() * estimate).translation().norm();
}

class LocalMapperTest : public ::testing::Test {
 protected:
  LocalMapperTest()
      : calibration_(pinhole()),
        camera_(calibration_),
        store_(kKeyframes + 1, kFeatures, 0, 0, 100),
        backend_(config(), calibration_.rgb.T_base_cam, false) {
    std::mt19937 random(5);
    std::uniform_real_distribution<double> across(-1.0, 1.0);
    std::uniform_real_distribution<double> depth(0.8, 2.0);
    std::uniform_int_distribution<int> byte(0, 255);
    for (int l = 0; l < kLandmarks; ++l) {
      landmarks_.emplace_back(across(random), 0.5 * across(random), depth(random));
      std::array<std::uint8_t, 32> descriptor{};
      for (auto& b : descriptor) b = static_cast<std::uint8_t>(byte(random));
      descriptors_.push_back(descriptor);
    }
    // 20 cm and 3 degrees between key-frames; each registration 6 mm and 0.2 degrees off.
    for (int k = 0; k < kKeyframes; ++k) truth_.push_back(pose(0.05 * k, Eigen::Vector3d(0.2 * k, 0.0, 0.03 * k)));
    tracked_.push_back(truth_[0]);
    for (int k = 1; k < kKeyframes; ++k) {
      const Eigen::Isometry3d off = pose(0.0035 * (k % 2 == 0 ? 1 : -1), Eigen::Vector3d(0.006, -0.002, 0.001));
      measured_.push_back(truth_[static_cast<std::size_t>(k - 1)].inverse() * truth_[static_cast<std::size_t>(k)] * off);
      tracked_.push_back(tracked_.back() * measured_.back());
    }
  }

  static const SlamConfig& config() {
    static const SlamConfig config = [] {
      SlamConfig c;
      c.mode = Mode::kPhotometric;
      c.rolling_shutter_readout_ms = 0.0;
      c.local.window = 5;
      return c;
    }();
    return config;
  }

  // Stores key-frame k at its tracked pose with the landmarks it sees, and its edge from k − 1.
  int store(int k, std::mt19937& random) {
    PhotometricFeatures features;
    features.reserve(kFeatures);
    std::normal_distribution<double> normal(0.0, 1.0);
    const Eigen::Isometry3d T_cam_world = truth_[static_cast<std::size_t>(k)].inverse();
    for (int l = 0; l < kLandmarks; ++l) {
      const Eigen::Vector3d p = T_cam_world * landmarks_[static_cast<std::size_t>(l)];
      const double u = kFx * p.x() / p.z() + 319.5;
      const double v = kFx * p.y() / p.z() + 239.5;
      if (p.z() < 0.5 || u < 0 || u > 639 || v < 0 || v > 479) continue;
      const double sigma = 5e-3 * p.z() * p.z();
      const Eigen::Vector3d seen = p + sigma / std::sqrt(3.0) * Eigen::Vector3d(normal(random), normal(random), normal(random));
      features.keypoints.emplace_back(static_cast<float>(u), static_cast<float>(v), 7.0F);
      features.points_cam.push_back(seen.cast<float>());
      features.sigma_m.push_back(static_cast<float>(sigma));
      std::memcpy(features.descriptor_storage.ptr(static_cast<int>(features.size()) - 1),
                  descriptors_[static_cast<std::size_t>(l)].data(), 32);
    }
    features.descriptors = features.descriptor_storage.rowRange(0, static_cast<int>(features.size()));
    const int slot = store_.free_slot();
    store_.occupy(slot);
    StoredKeyframe& keyframe = store_.slot(slot);
    keyframe.sequence = k + 1;
    keyframe.T_world_cam = tracked_[static_cast<std::size_t>(k)];
    KeyframeStore::copy_features(features, keyframe.photometric);
    keyframe.node = backend_.add_node(keyframe.T_world_cam, keyframe.generation);
    if (k > 0) {
      const StoredKeyframe& previous = store_.slot(slots_.back());
      backend_.add_sequential_edges(previous.node, keyframe.node, measured_[static_cast<std::size_t>(k - 1)],
                                    backend_.registration_information(30, 1.0));
    }
    slots_.push_back(slot);
    return slot;
  }

  // The graph's registration edge from key-frame k to k + 1.
  Eigen::Isometry3d edge(int k) const {
    const graph::PoseGraph& graph = backend_.graph();
    const int index = graph.find_edge(store_.slot(slots_[static_cast<std::size_t>(k)]).node,
                                      store_.slot(slots_[static_cast<std::size_t>(k + 1)]).node,
                                      graph::EdgeKind::kSequential);
    EXPECT_GE(index, 0);
    return graph.edge(index).T_from_to;
  }
  Eigen::Isometry3d truth(int k) const {
    return truth_[static_cast<std::size_t>(k)].inverse() * truth_[static_cast<std::size_t>(k + 1)];
  }

  hal::Calibration calibration_;
  camera::DepthCameraModel camera_;
  KeyframeStore store_;
  Backend backend_;
  std::vector<Eigen::Vector3d> landmarks_;
  std::vector<std::array<std::uint8_t, 32>> descriptors_;
  std::vector<Eigen::Isometry3d> truth_;
  std::vector<Eigen::Isometry3d> tracked_;
  std::vector<Eigen::Isometry3d> measured_;
  std::vector<int> slots_;
};

TEST_F(LocalMapperTest, EachEdgeIsRefinedOnceTowardsTheTruth) {
  LocalMapper mapper(config(), camera_, kFeatures);
  mapper.set_synchronous(true);
  ASSERT_TRUE(mapper.enabled());
  std::mt19937 random(9);
  for (int k = 0; k < kKeyframes; ++k) {
    (void)store(k, random);
    const bool submitted = mapper.submit(store_, backend_.graph());
    EXPECT_EQ(submitted, k >= 1) << "key-frame " << k;
    const int refined = mapper.take(backend_);
    // The window fills at the fifth key-frame: from then on its oldest edge is refined.
    EXPECT_EQ(refined, k >= 4 ? 1 : 0) << "key-frame " << k;
  }
  // Edges 0, 1 and 2 were the oldest of a full window; 3 to 5 keep their registrations, at the
  // end of the run too.
  mapper.finish(backend_);
  for (int k = 0; k < 3; ++k) {
    EXPECT_LT(edge_error_m(edge(k), truth(k)), 0.5 * edge_error_m(measured_[static_cast<std::size_t>(k)], truth(k)))
        << "edge " << k;
  }
  for (int k = 3; k + 1 < kKeyframes; ++k) {
    EXPECT_NEAR(edge_error_m(edge(k), measured_[static_cast<std::size_t>(k)]), 0.0, 1e-9) << "edge " << k;
  }
  const LocalMapCounters& counters = mapper.counters();
  EXPECT_EQ(counters.refined_edges, 3);
  EXPECT_EQ(counters.adjustments, kKeyframes - 1);  // one per key-frame after the first
  EXPECT_EQ(counters.failed, 0);
  EXPECT_GT(counters.landmarks, kLandmarks / 4);
  EXPECT_GT(counters.inlier_observations, 0.9 * counters.observations);
}

TEST_F(LocalMapperTest, AnEdgeWhoseKeyframeLeftTheGraphIsNotRefined) {
  LocalMapper mapper(config(), camera_, kFeatures);
  std::mt19937 random(9);
  for (int k = 0; k < 5; ++k) (void)store(k, random);
  // Not synchronous: the window goes to the mapping thread; the oldest key-frame leaves the graph
  // before the result is taken.
  ASSERT_TRUE(mapper.submit(store_, backend_.graph()));
  EXPECT_FALSE(mapper.submit(store_, backend_.graph())) << "one window at a time";
  backend_.remove_node(store_.slot(slots_[0]).node);
  EXPECT_EQ(mapper.take(backend_, true), 0);
  EXPECT_EQ(mapper.counters().adjustments, 1);
}

TEST_F(LocalMapperTest, OffBelowTwoKeyframes) {
  SlamConfig off = config();
  off.local.window = 1;
  LocalMapper mapper(off, camera_, kFeatures);
  EXPECT_FALSE(mapper.enabled());
  std::mt19937 random(9);
  (void)store(0, random);
  (void)store(1, random);
  EXPECT_FALSE(mapper.submit(store_, backend_.graph()));
  EXPECT_EQ(mapper.take(backend_, true), 0);
}

}  // namespace
}  // namespace rankslam::slam
