// SickLms1xxSim: a SICK LMS1xx speaking CoLa-A on a local TCP port, for developing and
// testing the SICK driver without hardware (tests, and `rack-devsim sick`).
//
// Answers sMN SetAccessMode, sRN LMDscandata (one scan) and sEN LMDscandata 1/0
// (continuous output, "sSN LMDscandata" telegrams with DIST1 and RSSI1, 541 points
// from -45 to 225 deg at 0.5 deg, 50 Hz by default). Other commands get "sFA" errors.
// The scanner stands in the middle of a rectangular room. One client at a time, as the
// driver connects. Faults: garbage between telegrams, truncated telegrams, silence,
// dropping the client, and closing the port (the sensor switched off).
//
// Not RT code: a plain thread; for tests and tools.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace rack::sims {

class SickLms1xxSim {
 public:
  struct Config {
    uint16_t port = 0;  // 0: any free port (see port())
    uint32_t frequency_centihz = 5000;
    int32_t start_angle = -450000;  // 1/10000 deg, SICK frame (90 deg ahead)
    uint32_t step = 5000;           // 0.5 deg
    uint32_t count = 541;
    double room_front = 2.0, room_side = 1.5;  // m
  };
  enum class Fault : uint8_t { kNone, kGarbage, kTruncated, kSilent };

  explicit SickLms1xxSim(Config config);
  ~SickLms1xxSim();
  SickLms1xxSim(const SickLms1xxSim&) = delete;
  SickLms1xxSim& operator=(const SickLms1xxSim&) = delete;

  void start();  // binds 127.0.0.1:port; throws std::system_error
  void stop();
  [[nodiscard]] uint16_t port() const { return port_; }
  void set_fault(Fault f) { fault_.store(f); }
  void drop_client() { drop_.store(true); }
  [[nodiscard]] bool streaming() const { return streaming_.load(); }
  [[nodiscard]] uint64_t scans_sent() const { return scans_.load(); }
  [[nodiscard]] double range_m(uint32_t index) const;  // what point `index` reports
  // Bytes from the driver, as run() receives them from the client: each STX..ETX
  // telegram is a command, answered to the client (nowhere without one). Only before
  // start() (run() owns the input then): for tests and tests/fuzz/fuzz_devsim.cpp.
  void receive(const char* data, std::size_t n);

 private:
  void run();
  void handle(const std::string& telegram);
  std::string scan_telegram(const char* kind);
  void send(const std::string& body);

  Config config_;
  uint16_t port_ = 0;
  int listen_fd_ = -1;
  int client_ = -1;
  std::string input_;
  uint32_t counter_ = 0;
  std::atomic<Fault> fault_{Fault::kNone};
  std::atomic<bool> stop_{false}, drop_{false}, streaming_{false};
  std::atomic<uint64_t> scans_{0};
  std::thread thread_;
};

}  // namespace rack::sims
