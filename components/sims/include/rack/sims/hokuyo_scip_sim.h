// HokuyoScipSim: a Hokuyo URG laser scanner speaking SCIP 2.0 on a pseudo-terminal,
// for developing and testing the Hokuyo driver without hardware (tests, and
// `rack-devsim hokuyo` on the command line).
//
// Answers SCIP2.0, VV, PP, BM, QT, GD and MD (continuous scans at the model's rate,
// 3-character encoding, 64-character data lines with checksums), with the URG-04LX's
// parameters by default. The scanner stands in the middle of a rectangular room.
// Faults: wrong checksums, garbage, silence, unplugging (plug() makes a new pty and
// moves the symlink).
//
// Not RT code: a plain thread; for tests and tools.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace rack::sims {

namespace detail {
class PtyDevice;
}

class HokuyoScipSim {
 public:
  struct Config {
    std::string link;  // symlink to the pty slave ("" = none)
    // URG-04LX.
    uint32_t dmin_mm = 20, dmax_mm = 5600, ares = 1024, amin = 44, amax = 725, afrt = 384, scan_rpm = 600;
    double room_front = 2.0;  // m from the scanner to the walls ahead/behind
    double room_side = 1.5;   // m to the walls left/right
  };
  enum class Fault : uint8_t { kNone, kBadChecksum, kGarbage, kSilent };

  explicit HokuyoScipSim(Config config);
  ~HokuyoScipSim();
  HokuyoScipSim(const HokuyoScipSim&) = delete;
  HokuyoScipSim& operator=(const HokuyoScipSim&) = delete;

  void start();  // throws std::system_error
  void stop();
  [[nodiscard]] std::string device() const;
  void set_fault(Fault f) { fault_.store(f); }
  void unplug();
  void plug();
  [[nodiscard]] uint64_t scans_sent() const { return scans_.load(); }
  [[nodiscard]] bool streaming() const { return streaming_.load(); }
  // The range the simulator reports for a step (mm), for tests.
  [[nodiscard]] uint32_t range_mm(uint32_t step) const;
  // Bytes from the driver, as run() reads them from the pty: each line (CR or LF) is a
  // command, answered on the pty (nowhere before start()). For tests and
  // tests/fuzz/fuzz_devsim.cpp, which drive the command parser without a pty.
  void receive(const char* data, std::size_t n);

 private:
  void run();
  void take(const char* data, std::size_t n);  // receive() with mutex_ held
  void handle_line(const std::string& line);
  void send_scan(const std::string& echo, const char* status, uint32_t first, uint32_t last, uint32_t cluster);
  void write(const std::string& s);

  Config config_;
  mutable std::mutex mutex_;
  std::unique_ptr<detail::PtyDevice> pty_;
  std::string input_;
  std::atomic<Fault> fault_{Fault::kNone};
  std::atomic<bool> stop_{false};
  std::atomic<bool> streaming_{false};
  std::atomic<uint64_t> scans_{0};
  uint32_t md_first_ = 0, md_last_ = 0, md_cluster_ = 1;
  std::string md_echo_;
  std::thread thread_;
};

}  // namespace rack::sims
