// Support for integration tests that run the real rackd and rackctl binaries:
// child processes with captured output, a watchdog, a private LCM bus per test and
// a temporary directory.
//
// Every child is started with PR_SET_PDEATHSIG(SIGKILL), so it dies with the test
// process, and is registered so the watchdog can kill it.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <condition_variable>
#include <filesystem>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace rack::test {

// The non-empty lines of a program's output, in order.
inline std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) out.push_back(line);
  }
  return out;
}

// What a finished child left behind.
struct RunResult {
  int exit_code = -1;  // -1 when killed by a signal (or by the timeout)
  int term_signal = 0;
  bool timed_out = false;  // killed because it ran past its bound
  std::string out;
  std::string err;
  [[nodiscard]] std::string describe() const;  // for assertion messages
};

// Runs `args` (args[0] is the path) to completion, capturing stdout and stderr.
// Killed (SIGKILL) after `timeout`. `netns`: the named network namespace
// (/run/netns/NAME) the child enters before exec; empty: the test's own.
RunResult run(const std::vector<std::string>& args, std::chrono::milliseconds timeout, const std::string& netns = "");

// A long-running child (rackd) whose stdout and stderr go to files in `dir`.
class Process {
 public:
  Process(const std::vector<std::string>& args, const std::filesystem::path& dir, const std::string& tag,
          const std::string& netns = "");
  ~Process();  // SIGKILL and reap if still running
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  [[nodiscard]] pid_t pid() const { return pid_; }
  [[nodiscard]] bool running();
  // Waits until stderr contains `text`; false on timeout or when the child exited.
  bool wait_for_stderr(const std::string& text, std::chrono::milliseconds timeout);
  void signal(int sig);
  // Exit code once the child exited within `timeout` (-1: killed by a signal);
  // nullopt when it is still running.
  std::optional<int> wait_exit(std::chrono::milliseconds timeout);
  [[nodiscard]] std::string out() const;
  [[nodiscard]] std::string err() const;
  // The signal that ended the child (0: it exited), once wait_exit() saw it end.
  [[nodiscard]] int term_signal() const { return term_signal_; }

 private:
  pid_t pid_ = -1;
  int term_signal_ = 0;
  std::optional<int> status_;
  std::filesystem::path out_path_, err_path_;
};

// Kills every registered child and ends the test process when a test runs past its
// bound (so a hang fails fast and leaves no rackd behind).
class Watchdog {
 public:
  Watchdog(std::chrono::seconds limit, std::string what);
  ~Watchdog();
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;
};

// A private LCM bus: a UDP port nobody else in these tests uses at the same time
// (an flock on a file per port, held for the object's lifetime, across processes).
class LcmBus {
 public:
  LcmBus();
  ~LcmBus();
  LcmBus(const LcmBus&) = delete;
  LcmBus& operator=(const LcmBus&) = delete;
  [[nodiscard]] std::string url() const;
  [[nodiscard]] int port() const { return port_; }

 private:
  int fd_ = -1;
  int port_ = 0;
};

// A fresh directory under $TMPDIR (or /tmp), removed with its contents.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  std::filesystem::path write(const std::string& name, const std::string& text) const;

 private:
  std::filesystem::path path_;
};

std::string read_file(const std::filesystem::path& path);

// Polls `pred` every 50 ms until it holds (true) or `bound` has passed (false). The
// integration tests wait for real processes this way; the bound only turns a hang into
// a failure (generous by design, never a timing assertion).
template <typename Pred>
bool eventually(Pred pred, std::chrono::milliseconds bound = std::chrono::seconds(20)) {
  const auto deadline = std::chrono::steady_clock::now() + bound;
  for (;;) {
    if (pred()) return true;
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
}

// The first executable `name` in $PATH (/usr/bin:/bin when PATH is unset), or nullopt:
// tests that need an outside tool (node, dot) skip with the reason when it is missing.
std::optional<std::string> find_program(const std::string& name);

// What the browser tests need (Playwright's scripts run by node, driving Chromium):
// node from $PATH and Chromium ($RACK_CHROMIUM, else /usr/bin/chromium).
struct BrowserTools {
  std::string node;      // its path, when installed
  std::string chromium;  // the path tried
  std::string missing;   // why a test must skip (what is not installed); empty: both are there
};
BrowserTools find_browser_tools();

// The address rack-gui serves on, once its stderr says "rack-gui: serving http://..."
// within `timeout`: "http://HOST:PORT/" as printed; "" when it did not say so.
std::string served_url(Process& gui, std::chrono::milliseconds timeout = std::chrono::seconds(15));
// The port of an "http://HOST:PORT/..." address (0 when it names none).
uint16_t port_of(const std::string& url);

}  // namespace rack::test
