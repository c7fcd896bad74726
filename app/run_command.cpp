#include "commands.hpp"
#include "exit_codes.hpp"

#include <iostream>

namespace rankslam::app {

int run_live(const RunArgs& args) {
  // Live operation needs the OpenNI2, V4L2 and SocketCAN drivers, which this build does not
  // contain yet; say so plainly instead of pretending to run.
  std::cerr << "error: live operation (rankslam run --config " << args.config.string()
            << ") needs the hardware drivers, which are not part of this build yet\n";
  return kExitNotAvailable;
}

}  // namespace rankslam::app
