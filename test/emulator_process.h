// Test helpers for the device emulators of test/emulators/: waiting for a condition, and an
// emulator child process (Python, standard library only) that is killed and reaped by its guard.
// Shared by test_rig_core, test_rig_emulators and the rig_emulated rostest.
#pragma once

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace hydrojet {
namespace test {

/// Polls `cond` every 5 ms until it holds or `timeout_s` seconds have passed; its final value.
template <class F>
bool eventually(F cond, double timeout_s) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < until) {
    if (cond()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return cond();
}

/// An emulator child process: `python3 test/emulators/<script> --exit-with-parent <args>`;
/// SIGTERM and reaped on destruction. With `wait_for`, the constructor waits (≤ 10 s) until that
/// path exists (the emulator's PTY link).
class Emulator {
 public:
  Emulator(const std::string& script, const std::vector<std::string>& args, const std::string& wait_for = "") {
    std::vector<std::string> argv = {"/usr/bin/python3", std::string(HYDROJET_SOURCE_DIR) + "/test/emulators/" + script,
                                     "--exit-with-parent"};
    argv.insert(argv.end(), args.begin(), args.end());
    std::vector<char*> cargv;
    for (auto& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
    cargv.push_back(nullptr);
    if (posix_spawn(&pid_, cargv[0], nullptr, nullptr, cargv.data(), environ) != 0) pid_ = -1;
    if (!wait_for.empty()) eventually([&] { return access(wait_for.c_str(), F_OK) == 0; }, 10.0);
  }
  Emulator(const Emulator&) = delete;
  Emulator& operator=(const Emulator&) = delete;
  ~Emulator() { kill(); }
  bool started() const { return pid_ > 0; }
  void kill() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    int st;
    waitpid(pid_, &st, 0);
    pid_ = -1;
  }
  /// True once the process has exited by itself (reaps it).
  bool exited() {
    if (pid_ <= 0) return true;
    int st;
    if (waitpid(pid_, &st, WNOHANG) == pid_) {
      pid_ = -1;
      return true;
    }
    return false;
  }

 private:
  pid_t pid_ = -1;
};

}  // namespace test
}  // namespace hydrojet
