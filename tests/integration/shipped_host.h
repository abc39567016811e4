// The prelude that the integration tests of the shipped host files share (trace,
// sim_nav, replay_end, replay_mcl): a copy of configs/NAME with its data paths made
// absolute, the real rackd on it on a private LCM bus, the real rackctl on the same
// bus, and a clean stop (SIGTERM, exit status 0) at the end. RackdOnBus serves tests of
// a host file of their own the same way (tims_input, hostile_net).
#pragma once

#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include "process.h"

namespace rack::test {

// configs/`name`'s text with its relative data paths (`log:`, `map:` and `reference:`
// naming logs/ or maps/) made absolute: the tests write their copy elsewhere.
inline std::string shipped_host_text(const std::string& name) {
  const std::string configs = RACK_CONFIGS_DIR;
  return std::regex_replace(read_file(configs + "/" + name), std::regex("(log|map|reference): (logs|maps)/"),
                            "$1: " + configs + "/$2/");
}

// rackd on a host file in a temporary directory of its own, on a private LCM bus.
class RackdOnBus {
 public:
  RackdOnBus() = default;
  // A rackd still running is stopped: SIGTERM, and it must exit 0 within 30 s.
  ~RackdOnBus() {
    if (rackd_ && rackd_->running()) {
      rackd_->signal(SIGTERM);
      EXPECT_EQ(rackd_->wait_exit(std::chrono::seconds(30)), std::optional<int>(0)) << rackd_->err();
    }
  }
  RackdOnBus(const RackdOnBus&) = delete;
  RackdOnBus& operator=(const RackdOnBus&) = delete;

  // Writes `text` as `file_name` into dir() and returns its path.
  std::string write(const std::string& file_name, const std::string& text) const {
    return dir_.write(file_name, text).string();
  }
  // Starts rackd on `path` with --lcm (and `extra` arguments); with `wait`, waits for
  // "rackd: running" up to 30 s.
  ::testing::AssertionResult start(const std::string& path, const std::vector<std::string>& extra = {},
                                   bool wait = true) {
    std::vector<std::string> args{RACK_RACKD_PATH, path, "--lcm", bus_.url()};
    args.insert(args.end(), extra.begin(), extra.end());
    rackd_ = std::make_unique<Process>(args, dir_.path(), "rackd");
    if (!wait || rackd_->wait_for_stderr("rackd: running", std::chrono::seconds(30))) {
      return ::testing::AssertionSuccess();
    }
    return ::testing::AssertionFailure() << "rackd did not say 'rackd: running':\n" << rackd_->err();
  }
  // rackctl on the same bus (discovery bounded to `discover_ms`), to completion within
  // 30 s.
  RunResult ctl(std::vector<std::string> args, const std::string& discover_ms = "3000") const {
    args.insert(args.begin(), {RACK_RACKCTL_PATH, "--lcm", bus_.url(), "--discover-ms", discover_ms});
    return run(args, std::chrono::seconds(30));
  }

  [[nodiscard]] Process& rackd() { return *rackd_; }
  [[nodiscard]] bool started() const { return rackd_ != nullptr; }
  [[nodiscard]] const TempDir& dir() const { return dir_; }
  [[nodiscard]] const LcmBus& bus() const { return bus_; }

 private:
  TempDir dir_;
  LcmBus bus_;
  std::unique_ptr<Process> rackd_;
};

}  // namespace rack::test
