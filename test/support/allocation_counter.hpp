#pragma once

// Counts heap allocations of the whole process (every thread) while a CountAllocations is alive:
// global operator new and, with glibc outside sanitizer builds, malloc itself, which Eigen's heap
// temporaries and OpenCV's buffers use without operator new. Linking this library into a test
// executable replaces the allocation functions of that executable; the fixed-memory tests use it
// to prove that per-frame code allocates nothing after set-up. Each thread's calls are also
// counted apart, for code whose other threads may allocate by design (a background solver).

namespace rankslam::test_support {

/// True where malloc-family calls are counted as well as operator new.
[[nodiscard]] bool counts_malloc();

class CountAllocations {
 public:
  CountAllocations();
  ~CountAllocations();
  CountAllocations(const CountAllocations&) = delete;
  CountAllocations& operator=(const CountAllocations&) = delete;

  /// operator new calls since construction.
  [[nodiscard]] long new_calls() const;
  /// malloc-family calls since construction (0 where counts_malloc() is false). A counted
  /// operator new calls malloc too, so one operator new may count in both.
  [[nodiscard]] long malloc_calls() const;
  /// Both together: zero is what the fixed-memory tests require.
  [[nodiscard]] long allocations() const { return new_calls() + malloc_calls(); }

  /// As above, counting only the calls of the thread that constructed this object; call these
  /// from that thread.
  [[nodiscard]] long this_thread_new_calls() const;
  [[nodiscard]] long this_thread_malloc_calls() const;
  [[nodiscard]] long this_thread_allocations() const { return this_thread_new_calls() + this_thread_malloc_calls(); }

 private:
  long thread_new_start_;
  long thread_malloc_start_;
};

}  // namespace rankslam::test_support
