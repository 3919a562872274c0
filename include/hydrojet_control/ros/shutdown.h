// SIGINT and SIGTERM end every node the same way: the node's loop stops, the node closes its valves
// (rig: duty 0 to the board; plant: its simulated valves shut; controller: an all-zero jets/command)
// while roscpp can still deliver messages, and only then does roscpp shut down. roscpp's own SIGINT
// handler would shut the transport down first (the closing command would be lost), and SIGTERM,
// the signal of `kill`, systemd and roslaunch's escalation, would end the process on the spot.
#pragma once

namespace hydrojet {
namespace ros_bridge {

/// Installs the SIGINT/SIGTERM handlers (a flag only: async-signal-safe). Call right after
/// ros::init(..., ros::init_options::NoSigintHandler).
void install_shutdown_signals();

/// The signal that asked the node to stop (SIGINT or SIGTERM), 0 while none has.
int shutdown_signal();

/// True while the node should keep running: ros::ok() and no signal received.
bool running();

/// ros::spin() that also returns when a signal arrives (callbacks every 10 ms or sooner).
void spin_until_signal();

/// Lets roscpp's transport deliver what was just published (the closing command) for `seconds` of
/// wall time, then shuts roscpp down.
void flush_and_shutdown(double seconds = 0.3);

}  // namespace ros_bridge
}  // namespace hydrojet
