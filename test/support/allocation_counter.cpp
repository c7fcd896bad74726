#include "allocation_counter.hpp"

#include <atomic>
#include <cerrno>
#include <cstddef>
#include <cstdlib>
#include <new>

namespace {

std::atomic<bool> g_counting{false};
std::atomic<long> g_new_calls{0};
std::atomic<long> g_malloc_calls{0};
// The calling thread's calls while counting. Initial-exec TLS: the executable's own static TLS
// block, read without __tls_get_addr, which may itself call malloc.
thread_local long t_new_calls __attribute__((tls_model("initial-exec"))) = 0;
thread_local long t_malloc_calls __attribute__((tls_model("initial-exec"))) = 0;

void note_new() {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_new_calls.fetch_add(1, std::memory_order_relaxed);
    ++t_new_calls;
  }
}

[[maybe_unused]] void note_malloc() {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_malloc_calls.fetch_add(1, std::memory_order_relaxed);
    ++t_malloc_calls;
  }
}

[[maybe_unused]] void* counted_new(std::size_t size) {
  note_new();
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}

[[maybe_unused]] void* counted_new_aligned(std::size_t size, std::align_val_t alignment) {
  note_new();
  const auto align = static_cast<std::size_t>(alignment);
  const std::size_t rounded = ((size == 0 ? 1 : size) + align - 1) / align * align;
  if (void* p = std::aligned_alloc(align, rounded)) return p;
  throw std::bad_alloc();
}

}  // namespace

#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define RANKSLAM_TSAN 1
#endif
#endif
#if defined(__SANITIZE_THREAD__) || defined(RANKSLAM_TSAN)
// ThreadSanitizer's runtime brings its own operator new, which cannot be replaced: nothing is
// counted there, and the tsan test preset leaves the allocation tests out.
#else
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
void* operator new(std::size_t size, std::align_val_t alignment) { return counted_new_aligned(size, alignment); }
void* operator new[](std::size_t size, std::align_val_t alignment) { return counted_new_aligned(size, alignment); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
#endif

// glibc lets a program replace malloc; forwarding to its __libc_* entry points keeps one heap.
// Sanitizers interpose malloc themselves, so there only operator new is counted (GCC says so with
// __SANITIZE_*__, clang with __has_feature).
#if defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
#define RANKSLAM_SANITIZED 1
#endif
#endif
#if defined(__GLIBC__) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__) && !defined(RANKSLAM_SANITIZED)
#define RANKSLAM_COUNT_MALLOC 1
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);

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

namespace rankslam::test_support {

bool counts_malloc() {
#ifdef RANKSLAM_COUNT_MALLOC
  return true;
#else
  return false;
#endif
}

CountAllocations::CountAllocations() : thread_new_start_(t_new_calls), thread_malloc_start_(t_malloc_calls) {
  g_new_calls = 0;
  g_malloc_calls = 0;
  g_counting = true;
}

CountAllocations::~CountAllocations() { g_counting = false; }

long CountAllocations::new_calls() const { return g_new_calls.load(); }

long CountAllocations::malloc_calls() const { return g_malloc_calls.load(); }

long CountAllocations::this_thread_new_calls() const { return t_new_calls - thread_new_start_; }

long CountAllocations::this_thread_malloc_calls() const { return t_malloc_calls - thread_malloc_start_; }

}  // namespace rankslam::test_support
