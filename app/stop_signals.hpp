#pragma once

namespace rankslam::app {

/// Turns SIGINT and SIGTERM into a request to stop for the rest of the process: the loop polls
/// stop_requested(), and a signal while the outputs are written, or while the process tears down
/// after them, no longer kills it half-way; the command finishes its outputs and exits 130.
/// `restart_system_calls`: SA_RESTART, so a signal does not fail a blocking call with EINTR.
void defer_stop_signals(bool restart_system_calls);

/// Whether SIGINT or SIGTERM came since defer_stop_signals().
[[nodiscard]] bool stop_requested();

}  // namespace rankslam::app
