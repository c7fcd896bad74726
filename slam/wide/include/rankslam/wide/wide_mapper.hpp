#pragma once

#include "rankslam/camera/virtual_views.hpp"
#include "rankslam/hal/calibration.hpp"
#include "rankslam/wide/features.hpp"
#include "rankslam/wide/mono_registrar.hpp"
#include "rankslam/wide/vlad.hpp"

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <array>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <span>
#include <thread>
#include <vector>

namespace rankslam::wide {

/// What the wide-angle mapper does and keeps.
struct WideMapperOptions {
  /// Key-frame slots whose RGB-D features are kept: the key-frame store's capacity.
  int capacity = 128;
  SiftOptions sift;
  MonoRegistrationOptions registration;
  camera::VirtualViewOptions views;
  /// Place recognition's words; null: the built-in vocabulary. Copied at construction.
  const Vocabulary* vocabulary = nullptr;
};

/// A stored key-frame a wide-angle image is registered to: its slot and its sequence there (a
/// slot reused since holds another key-frame, and is passed over).
struct WideCandidate {
  int slot = -1;
  std::int64_t sequence = 0;
};

/// One wide-angle image's registrations to stored key-frames: the RGBD–mono edges of the
/// monocular node, which sits rigidly on its key-frame (the image was taken with a frame tracked
/// from it, through the cameras' calibrated mounting).
struct WideEdge {
  WideCandidate stored;
  /// The stored key-frame's colour camera in the frame of the key-frame the image belongs to.
  Eigen::Isometry3d T_keyframe_stored = Eigen::Isometry3d::Identity();
  /// Information over δ = (rotation vector, translation) for T_keyframe_stored ← T_keyframe_stored·exp(δ),
  /// the pose graph's convention for an edge from the key-frame to the stored one.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Zero();
  int inliers = 0;
  double position_sigma_m = 0.0;
  /// VLAD similarity of the stored key-frame to the image's most similar virtual view.
  float similarity = 0.0F;
};

struct WideResult {
  static constexpr int kMaxEdges = 8;
  /// The key-frame the image belongs to.
  WideCandidate keyframe;
  int wide_features = 0;
  int rgbd_features = 0;
  /// Candidates registered (those still holding their key-frame) and the edges found.
  int tried = 0;
  int edge_count = 0;
  std::array<WideEdge, kMaxEdges> edges;
};

/// What the loop hands the mapper at a key-frame: a frame tracked from the key-frame, its
/// paired wide-angle image, and the stored key-frames to register the image to.
struct WideSubmission {
  const cv::Mat* colour = nullptr;  ///< the frame's colour image, CV_8UC3 at the RGB-D calibration's size
  const cv::Mat* depth = nullptr;   ///< its depth, CV_16UC1
  const cv::Mat* wide = nullptr;    ///< the wide-angle image, CV_8UC3 or CV_8UC1 at its calibration's size
  WideCandidate keyframe;
  /// The frame's colour camera in the key-frame's.
  Eigen::Isometry3d T_keyframe_frame = Eigen::Isometry3d::Identity();
  std::span<const WideCandidate> candidates;  ///< at most WideResult::kMaxEdges
  /// Stored key-frames the image may also be registered to, by place recognition: the
  /// `place_count` whose VLAD is most similar to one of the image's virtual views' (§6.4).
  /// At most the mapper's capacity; those among `candidates` are passed over.
  std::span<const WideCandidate> places;
  int place_count = 0;
};

/// What the mapper has done.
struct WideMapperCounters {
  std::uint64_t submitted = 0;  ///< images taken into the queue
  std::uint64_t dropped = 0;    ///< images refused: the queue was full, or the images had the wrong size
  std::uint64_t done = 0;
};

/// The wide-angle camera's work beside tracking (ALGORITHMS.md §6.3–§6.5), on a thread of its
/// own behind a queue of kJobs: per key-frame, SIFT on the frame's colour image (kept per
/// key-frame slot, its points moved into the key-frame's frame) and on the nine virtual views of
/// its wide-angle image, then the image registered to the stored key-frames it was given (P3P +
/// MSSE on the rays), to the key-frames it was given and to those of the places it was offered
/// whose VLAD is nearest the views'. The images' buffers, the queue and the per-slot features are allocated at
/// construction; the loop's thread copies into them and allocates nothing.
class WideMapper {
 public:
  static constexpr int kJobs = 2;

  /// `calibration` must hold `fisheye`. Allocates everything; starts the thread.
  WideMapper(const hal::Calibration& calibration, const WideMapperOptions& options);
  ~WideMapper();
  WideMapper(const WideMapper&) = delete;
  WideMapper& operator=(const WideMapper&) = delete;

  /// Loop's thread: queues the key-frame's images (copied). False, counted as dropped, when the
  /// queue is full or an image has the wrong size or type.
  bool submit(const WideSubmission& submission);
  /// Waits until every queued image is done.
  void wait_idle();
  /// Loop's thread: hands each finished result to `apply`, in submission order; no allocation.
  template <class Apply>
  void take_results(Apply&& apply) {
    for (;;) {
      {
        std::lock_guard lock(mutex_);
        Job* oldest = nullptr;
        for (auto& job : jobs_) {
          if (job.state == State::kDone && (oldest == nullptr || job.order < oldest->order)) oldest = &job;
        }
        if (oldest == nullptr) return;
        taken_ = oldest->result;
        oldest->state = State::kFree;
      }
      apply(static_cast<const WideResult&>(taken_));
    }
  }
  [[nodiscard]] WideMapperCounters counters() const;
  /// The wide-angle camera's colour camera mounting: T_rgb_wide maps the wide-angle camera's
  /// frame into the colour camera's.
  [[nodiscard]] const Eigen::Isometry3d& T_rgb_wide() const { return T_rgb_wide_; }

 private:
  /// kFilling: the loop's thread is copying into it, outside the lock.
  enum class State { kFree, kFilling, kQueued, kWorking, kDone };
  struct Job {
    State state = State::kFree;
    std::uint64_t order = 0;
    cv::Mat colour;
    cv::Mat depth;
    cv::Mat wide;
    WideCandidate keyframe;
    Eigen::Isometry3d T_keyframe_frame = Eigen::Isometry3d::Identity();
    std::array<WideCandidate, WideResult::kMaxEdges> candidates;
    int candidate_count = 0;
    std::vector<WideCandidate> places;  ///< capacity reserved at set-up
    int place_count = 0;
    WideResult result;
  };

  void work();
  void process(Job& job);
  /// Adds to the job's candidates the places whose VLAD is nearest the views' in view_vlad_.
  void choose_places(Job& job);
  [[nodiscard]] bool holds(const WideCandidate& candidate) const;

  Eigen::Isometry3d T_rgb_wide_;
  camera::VirtualViews views_;
  WideFeatureExtractor wide_extractor_;
  RgbdFeatureExtractor rgbd_extractor_;
  MonoRegistrar registrar_;
  WideFeatures wide_features_;
  RgbdFeatures frame_features_;
  /// Per key-frame slot: its features (points in the key-frame's frame) and its sequence (-1: none).
  std::vector<RgbdFeatures> stored_;
  std::vector<std::int64_t> stored_sequence_;
  std::vector<cv::Mat> stored_descriptors_;  ///< each slot's descriptor rows, allocated at set-up
  Vocabulary vocabulary_;
  cv::Mat stored_vlad_;  ///< per slot, its key-frame's VLAD (a row)
  cv::Mat view_vlad_;    ///< per virtual view of the image in hand, its VLAD (a row)
  std::vector<std::pair<float, int>> place_scores_;  ///< (similarity, index into the job's places)

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::array<Job, kJobs> jobs_;
  WideResult taken_;
  std::uint64_t next_order_ = 0;
  WideMapperCounters counters_;
  bool stop_ = false;
  std::thread thread_;  // last: starts once everything it uses exists
};

}  // namespace rankslam::wide
