#pragma once

namespace rankslam::app {

/// Process exit codes, documented in README ("Exit codes").
enum ExitCode : int {
  kExitOk = 0,
  kExitInternal = 1,        ///< An unexpected error inside rankslam.
  kExitUsage = 2,           ///< Bad command line.
  kExitInput = 3,           ///< A recording, configuration or trajectory could not be read.
  kExitOutput = 4,          ///< An output could not be written.
  kExitInterrupted = 130,   ///< Stopped by SIGINT/SIGTERM after flushing outputs.
};

}  // namespace rankslam::app
