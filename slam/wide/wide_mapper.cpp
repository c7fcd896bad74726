#include "rankslam/wide/wide_mapper.hpp"

#include "rankslam/core/lie.hpp"

#include <opencv2/core.hpp>

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <stdexcept>

namespace rankslam::wide {

namespace {

const hal::CameraCalibration& wide_calibration(const hal::Calibration& calibration) {
  if (!calibration.fisheye) throw std::invalid_argument("the calibration has no wide-angle camera (cameras.fisheye)");
  return *calibration.fisheye;
}

/// Information of T = C·A over the pose graph's right perturbation δ = (rotation, translation),
/// T ← T·exp(δ), from A's information over its left perturbation ξ = (translation, rotation),
/// A ← exp(ξ)·A: C·exp(ξ)·A = T·exp(Ad(A⁻¹)·ξ), so ξ = Ad(A)·δ.
Eigen::Matrix<double, 6, 6> edge_information(const Eigen::Isometry3d& A, const Eigen::Matrix<double, 6, 6>& H_left) {
  Eigen::Matrix<double, 6, 6> H;  // reordered to (rotation, translation), as lie::adjoint takes twists
  H.topLeftCorner<3, 3>() = H_left.bottomRightCorner<3, 3>();
  H.bottomRightCorner<3, 3>() = H_left.topLeftCorner<3, 3>();
  H.topRightCorner<3, 3>() = H_left.bottomLeftCorner<3, 3>();
  H.bottomLeftCorner<3, 3>() = H_left.topRightCorner<3, 3>();
  const Eigen::Matrix<double, 6, 6> adjoint = lie::adjoint(A);
  const Eigen::Matrix<double, 6, 6> out = adjoint.transpose() * H * adjoint;
  return 0.5 * (out + out.transpose());
}

/// Row `r` of a CV_32F matrix.
std::span<float> row_of(cv::Mat& m, int r) { return {m.ptr<float>(r), static_cast<std::size_t>(m.cols)}; }

}  // namespace

WideMapper::WideMapper(const hal::Calibration& calibration, const WideMapperOptions& options)
    : T_rgb_wide_(calibration.rgb.T_base_cam.inverse() * wide_calibration(calibration).T_base_cam),
      views_(*calibration.fisheye, calibration.rgb, options.views),
      wide_extractor_(views_, options.sift),
      rgbd_extractor_(camera::DepthCameraModel(calibration), options.sift),
      registrar_(options.registration),
      stored_(static_cast<std::size_t>(std::max(options.capacity, 0))),
      stored_sequence_(stored_.size(), -1),
      vocabulary_(options.vocabulary != nullptr ? *options.vocabulary : Vocabulary::built_in()) {
  const int n = options.sift.features_per_image;
  stored_vlad_.create(std::max(options.capacity, 1), vocabulary_.vlad_size(), CV_32F);
  view_vlad_.create(views_.count(), vocabulary_.vlad_size(), CV_32F);
  place_scores_.reserve(stored_.size());
  stored_descriptors_.resize(stored_.size());
  for (std::size_t i = 0; i < stored_.size(); ++i) {
    stored_[i].points.resize(3, n);
    stored_[i].pixel.reserve(static_cast<std::size_t>(n));
    stored_descriptors_[i].create(n, 128, CV_32F);
  }
  for (auto& job : jobs_) {
    job.colour.create(calibration.rgb.height, calibration.rgb.width, CV_8UC3);
    job.depth.create(calibration.rgb.height, calibration.rgb.width, CV_16UC1);
    job.wide.create(calibration.fisheye->height, calibration.fisheye->width, CV_8UC3);
    job.places.reserve(stored_.size());
  }
  thread_ = std::thread([this] { work(); });
}

WideMapper::~WideMapper() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

bool WideMapper::submit(const WideSubmission& submission) {
  std::unique_lock lock(mutex_);
  Job* free = nullptr;
  for (auto& job : jobs_) {
    if (job.state == State::kFree) {
      free = &job;
      break;
    }
  }
  const auto fits = [](const cv::Mat* image, const cv::Mat& buffer, bool grey_too) {
    return image != nullptr && image->size() == buffer.size() &&
           (image->type() == buffer.type() || (grey_too && image->type() == CV_8UC1));
  };
  if (free == nullptr || !fits(submission.colour, free->colour, false) || !fits(submission.depth, free->depth, false) ||
      !fits(submission.wide, free->wide, true) || submission.keyframe.slot < 0 ||
      submission.keyframe.slot >= static_cast<int>(stored_.size())) {
    ++counters_.dropped;
    return false;
  }
  // The copies are made outside the lock: the job is the caller's until it is queued.
  free->state = State::kFilling;
  lock.unlock();
  submission.colour->copyTo(free->colour);
  submission.depth->copyTo(free->depth);
  if (submission.wide->type() == CV_8UC1) {
    // Same-size conversion into the slot's buffer: no allocation.
    cv::Mat channels[] = {*submission.wide, *submission.wide, *submission.wide};
    cv::merge(channels, 3, free->wide);
  } else {
    submission.wide->copyTo(free->wide);
  }
  free->keyframe = submission.keyframe;
  free->T_keyframe_frame = submission.T_keyframe_frame;
  free->candidate_count = 0;
  for (const WideCandidate& candidate : submission.candidates) {
    if (free->candidate_count == WideResult::kMaxEdges) break;
    free->candidates[static_cast<std::size_t>(free->candidate_count++)] = candidate;
  }
  free->places.clear();
  for (const WideCandidate& place : submission.places) {
    if (free->places.size() == stored_.size()) break;
    free->places.push_back(place);
  }
  free->place_count = std::clamp(submission.place_count, 0, WideResult::kMaxEdges - free->candidate_count);
  lock.lock();
  free->state = State::kQueued;
  free->order = next_order_++;
  ++counters_.submitted;
  lock.unlock();
  wake_.notify_one();
  return true;
}

void WideMapper::wait_idle() {
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [this] {
    for (const auto& job : jobs_) {
      if (job.state == State::kQueued || job.state == State::kWorking) return false;
    }
    return true;
  });
}

WideMapperCounters WideMapper::counters() const {
  std::lock_guard lock(mutex_);
  return counters_;
}

void WideMapper::work() {
  // Below the loop's priority: the wide-angle work takes what tracking leaves of the CPU.
  (void)::setpriority(PRIO_PROCESS, static_cast<id_t>(::gettid()), 10);
  std::unique_lock lock(mutex_);
  for (;;) {
    Job* next = nullptr;
    wake_.wait(lock, [&] {
      next = nullptr;
      for (auto& job : jobs_) {
        if (job.state == State::kQueued && (next == nullptr || job.order < next->order)) next = &job;
      }
      return stop_ || next != nullptr;
    });
    if (stop_) return;
    next->state = State::kWorking;
    lock.unlock();
    process(*next);
    lock.lock();
    next->state = State::kDone;
    ++counters_.done;
    idle_.notify_all();
  }
}

bool WideMapper::holds(const WideCandidate& candidate) const {
  return candidate.slot >= 0 && candidate.slot < static_cast<int>(stored_.size()) &&
         stored_sequence_[static_cast<std::size_t>(candidate.slot)] == candidate.sequence;
}

void WideMapper::choose_places(Job& job) {
  place_scores_.clear();
  for (std::size_t p = 0; p < job.places.size(); ++p) {
    const WideCandidate& place = job.places[p];
    const auto already = job.candidates.begin() + job.candidate_count;
    if (!holds(place) || std::find_if(job.candidates.begin(), already, [&](const WideCandidate& c) {
                           return c.slot == place.slot && c.sequence == place.sequence;
                         }) != already) {
      continue;
    }
    float best = -1.0F;
    for (int v = 0; v < view_vlad_.rows; ++v) {
      best = std::max(best, vlad_similarity(row_of(view_vlad_, v), row_of(stored_vlad_, place.slot)));
    }
    place_scores_.emplace_back(best, static_cast<int>(p));
  }
  const auto n = std::min(place_scores_.size(), static_cast<std::size_t>(job.place_count));
  // Most similar first; the earlier place (the nearer, as the loop lists them) breaks a tie.
  std::partial_sort(place_scores_.begin(), place_scores_.begin() + static_cast<std::ptrdiff_t>(n), place_scores_.end(),
                    [](const auto& a, const auto& b) { return a.first > b.first || (a.first == b.first && a.second < b.second); });
  for (std::size_t i = 0; i < n && job.candidate_count < WideResult::kMaxEdges; ++i) {
    job.candidates[static_cast<std::size_t>(job.candidate_count++)] =
        job.places[static_cast<std::size_t>(place_scores_[i].second)];
  }
}

void WideMapper::process(Job& job) {
  WideResult& result = job.result;
  result = WideResult{};
  result.keyframe = job.keyframe;
  if (wide_extractor_.extract(job.wide, wide_features_)) result.wide_features = wide_features_.count;
  // Each view's VLAD, from its rows of the descriptors (the extractor keeps them in view order).
  for (int v = 0, begin = 0; v < view_vlad_.rows; ++v) {
    int end = begin;
    while (end < wide_features_.count && wide_features_.view[static_cast<std::size_t>(end)] == v) ++end;
    encode_vlad(vocabulary_, end > begin ? wide_features_.descriptors.rowRange(begin, end) : cv::Mat(), row_of(view_vlad_, v));
    begin = end;
  }
  if (result.wide_features > 0 && job.place_count > 0) choose_places(job);
  // The image was taken with the frame: T_keyframe_wide = T_keyframe_frame · T_rgb_wide.
  const Eigen::Isometry3d T_keyframe_wide = job.T_keyframe_frame * T_rgb_wide_;
  for (int c = 0; c < job.candidate_count && result.wide_features > 0; ++c) {
    const WideCandidate& candidate = job.candidates[static_cast<std::size_t>(c)];
    if (!holds(candidate)) continue;
    ++result.tried;
    const MonoRegistration registration =
        registrar_.register_frames(stored_[static_cast<std::size_t>(candidate.slot)], wide_features_);
    if (!registration.ok) continue;
    WideEdge& edge = result.edges[static_cast<std::size_t>(result.edge_count++)];
    edge.stored = candidate;
    edge.T_keyframe_stored = T_keyframe_wide * registration.T_wide_rgbd;
    edge.information = edge_information(registration.T_wide_rgbd, registration.information);
    edge.inliers = registration.inliers;
    edge.position_sigma_m = registration.position_sigma_m;
    for (int v = 0; v < view_vlad_.rows; ++v) {
      edge.similarity = std::max(edge.similarity, vlad_similarity(row_of(view_vlad_, v), row_of(stored_vlad_, candidate.slot)));
    }
  }
  // The key-frame's own features, for the images that come later.
  const auto slot = static_cast<std::size_t>(job.keyframe.slot);
  stored_sequence_[slot] = -1;
  if (rgbd_extractor_.extract(job.colour, job.depth, frame_features_)) {
    RgbdFeatures& stored = stored_[slot];
    const int n = std::min(frame_features_.count, static_cast<int>(stored.points.cols()));
    stored.count = n;
    stored.points.leftCols(n) = job.T_keyframe_frame * frame_features_.points.leftCols(n);
    // A header on the slot's buffer: the matcher sees the key-frame's rows alone.
    stored.descriptors = stored_descriptors_[slot].rowRange(0, n);
    frame_features_.descriptors.rowRange(0, n).copyTo(stored.descriptors);
    stored.pixel.assign(frame_features_.pixel.begin(), frame_features_.pixel.begin() + n);
    encode_vlad(vocabulary_, stored.descriptors, row_of(stored_vlad_, job.keyframe.slot));
    result.rgbd_features = n;
    stored_sequence_[slot] = job.keyframe.sequence;
  }
}

}  // namespace rankslam::wide
