#pragma once

// Counts heap allocations of the whole process (every thread) while a CountAllocations is
// alive: global operator new and, with glibc, malloc itself, which OpenCV's buffers use.
// Linked into the VM test executables to prove the drivers' steady-state loops allocate nothing.

namespace rankslam::vm_test {

class CountAllocations {
 public:
  CountAllocations();
  ~CountAllocations();
  CountAllocations(const CountAllocations&) = delete;
  CountAllocations& operator=(const CountAllocations&) = delete;
  /// operator new plus malloc-family calls since construction.
  [[nodiscard]] long allocations() const;
};

}  // namespace rankslam::vm_test
