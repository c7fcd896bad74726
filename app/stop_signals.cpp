#include "stop_signals.hpp"

#include <atomic>
#include <csignal>

namespace rankslam::app {
namespace {

std::atomic<bool> g_stop_requested{false};

extern "C" void request_stop(int /*signal*/) { g_stop_requested.store(true); }

}  // namespace

void defer_stop_signals(bool restart_system_calls) {
  g_stop_requested = false;
  struct sigaction action {};
  action.sa_handler = request_stop;
  action.sa_flags = restart_system_calls ? SA_RESTART : 0;
  sigemptyset(&action.sa_mask);
  sigaction(SIGINT, &action, nullptr);
  sigaction(SIGTERM, &action, nullptr);
}

bool stop_requested() { return g_stop_requested.load(); }

}  // namespace rankslam::app
