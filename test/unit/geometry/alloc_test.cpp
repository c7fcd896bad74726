// Fixed memory in the per-frame loop: after set-up and one warm-up frame, extract() and
// register_frames() (cloud, keypoints, SHOT, matching, MSSE, ICP) allocate nothing. Counts global
// operator new/delete (replaced below) and, outside sanitizer builds, malloc itself, because
// Eigen's heap temporaries bypass operator new.

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>

#include <gtest/gtest.h>

#include "rankslam/geometry/frontend.hpp"
#include "rankslam/slam/camera.hpp"
#include "synthetic_scene.hpp"

namespace {

std::atomic<bool> g_counting{false};
std::atomic<long> g_new_calls{0};
std::atomic<long> g_malloc_calls{0};

void* counted_new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_new_calls.fetch_add(1);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}

void* counted_new_aligned(std::size_t size, std::align_val_t alignment) {
  if (g_counting.load(std::memory_order_relaxed)) g_new_calls.fetch_add(1);
  const auto align = static_cast<std::size_t>(alignment);
  const std::size_t rounded = ((size == 0 ? 1 : size) + align - 1) / align * align;
  if (void* p = std::aligned_alloc(align, rounded)) return p;
  throw std::bad_alloc();
}

}  // namespace

void* operator new(std::size_t size) { return counted_new(size); }
void* operator new[](std::size_t size) { return counted_new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  try {
    return counted_new(size);
  } catch (...) {
    return nullptr;
  }
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  try {
    return counted_new(size);
  } catch (...) {
    return nullptr;
  }
}
void* operator new(std::size_t size, std::align_val_t alignment) {
  return counted_new_aligned(size, alignment);
}
void* operator new[](std::size_t size, std::align_val_t alignment) {
  return counted_new_aligned(size, alignment);
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

// glibc lets a program replace malloc; forwarding to its __libc_* entry points keeps one heap.
// Sanitizers interpose malloc themselves, so there only operator new is counted.
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
#define RANKSLAM_COUNT_MALLOC 1
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);

namespace {
void note_malloc() {
  if (g_counting.load(std::memory_order_relaxed)) g_malloc_calls.fetch_add(1);
}
}  // namespace

void* malloc(std::size_t size) noexcept {
  note_malloc();
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  note_malloc();
  return __libc_calloc(count, size);
}
void* realloc(void* p, std::size_t size) noexcept {
  note_malloc();
  return __libc_realloc(p, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  note_malloc();
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  note_malloc();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  note_malloc();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void free(void* p) noexcept { __libc_free(p); }
}  // extern "C"
#endif
namespace rankslam::geometry {
namespace {

class CountAllocations {
 public:
  CountAllocations() {
    g_new_calls = 0;
    g_malloc_calls = 0;
    g_counting = true;
  }
  ~CountAllocations() { g_counting = false; }
  CountAllocations(const CountAllocations&) = delete;
  CountAllocations& operator=(const CountAllocations&) = delete;
  long new_calls() const { return g_new_calls.load(); }
  long malloc_calls() const { return g_malloc_calls.load(); }
};

TEST(GeometryAllocations, CounterSeesAllocations) {
  long new_calls = 0;
  long malloc_calls = 0;
  {
    CountAllocations count;
    auto* v = new std::vector<double>(100, 1.0);
    const Eigen::VectorXd x = Eigen::VectorXd::Ones(1000);
    volatile double sink = x.sum() + (*v)[3];
    (void)sink;
    delete v;
    new_calls = count.new_calls();
    malloc_calls = count.malloc_calls();
  }
  EXPECT_GE(new_calls, 2);
#ifdef RANKSLAM_COUNT_MALLOC
  EXPECT_GE(malloc_calls, 3);
#else
  (void)malloc_calls;
#endif
}

TEST(GeometryAllocations, NoneInTheSteadyState) {
  const slam::DepthCameraModel camera(testing::test_calibration(), 5000.0);
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 6; ++i) {
    const Eigen::Isometry3d T_world_cam =
        testing::look_at(Eigen::Vector3d(2.6 + 0.05 * i, 2.4 - 0.04 * i, 1.7), Eigen::Vector3d(0.9, 0.9, 0.3));
    frames.push_back(testing::render_depth(testing::room_corner(), testing::test_calibration(), T_world_cam, 1.4e-3,
                                           static_cast<std::uint32_t>(i + 1)));
  }
  for (const KeypointMethod method : {KeypointMethod::kIs3d, KeypointMethod::kRos, KeypointMethod::kUniform}) {
    GeometryConfig config;
    config.keypoint_method = method;
    GeometricFrontend frontend;
    ASSERT_EQ(frontend.configure(camera, config), "");
    GeometricFeatures previous = frontend.make_features();
    GeometricFeatures current = frontend.make_features();
    GeometricCorrespondences correspondences = frontend.make_correspondences();
    // Warm-up: the first frames may touch lazily initialised state (none is expected).
    ASSERT_EQ(frontend.extract(frames[0], previous), GeometryStatus::kOk);
    ASSERT_EQ(frontend.extract(frames[1], current), GeometryStatus::kOk);
    ASSERT_TRUE(frontend.register_frames(previous, current).ok);

    long new_calls = 0;
    long malloc_calls = 0;
    int registered = 0;
    {
      CountAllocations count;
      for (std::size_t i = 2; i < frames.size(); ++i) {
        std::swap(previous, current);
        if (frontend.extract(frames[i], current) != GeometryStatus::kOk) continue;
        (void)frontend.correspondences(previous, current, correspondences);
        registered += frontend.register_frames(previous, current).ok ? 1 : 0;
      }
      new_calls = count.new_calls();
      malloc_calls = count.malloc_calls();
    }
    EXPECT_EQ(registered, 4) << to_string(method);
    EXPECT_EQ(new_calls, 0) << to_string(method);
    EXPECT_EQ(malloc_calls, 0) << to_string(method);
  }
}

}  // namespace
}  // namespace rankslam::geometry
