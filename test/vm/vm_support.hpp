#pragma once

// Helpers for the tests that run inside the VM (test/vm/run-in-vm.sh sets RANKSLAM_VM=1).
// Inside the VM every kernel facility must be there, so a missing one fails the test; run
// directly on a host without them, the tests skip and say how to run them.

#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cstdlib>
#include <string>

namespace rankslam::vm_test {

inline bool in_vm() { return std::getenv("RANKSLAM_VM") != nullptr; }

/// Runs a shell command in the VM; its exit status (-1 when it could not run).
inline int shell(const std::string& command) {
  const int status = std::system(command.c_str());
  if (status < 0 || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

/// Directory whose files are kept on the host (empty outside the VM).
inline std::string output_dir() {
  const char* dir = std::getenv("RANKSLAM_VM_OUT");
  return dir != nullptr ? dir : "";
}

}  // namespace rankslam::vm_test

/// Fails inside the VM, skips elsewhere, when `condition` does not hold.
#define RANKSLAM_VM_REQUIRE(condition, message)                                                       \
  do {                                                                                                \
    if (!(condition)) {                                                                               \
      if (::rankslam::vm_test::in_vm()) FAIL() << message;                                            \
      GTEST_SKIP() << message << " (this test needs a real kernel: run it through test/vm/run-in-vm.sh)"; \
    }                                                                                                 \
  } while (false)
