// NmeaGpsSim: a GNSS receiver on a pseudo-terminal, for developing and testing the GPS
// driver without hardware (tests, and `rack-devsim gps` on the command line).
//
// It opens a pty pair, optionally symlinks the slave to a stable path (a robot's
// udev rule gives the real receiver one, e.g. /dev/gps0), and writes GGA, RMC, GSA
// and VTG once per period for a receiver moving at constant speed and course from a
// start position. Faults can be switched on at run time: wrong checksums, garbage
// between sentences, silence (the receiver stops talking), and unplugging (the pty
// closes; plug() makes a new one and moves the symlink, like a USB receiver that comes
// back under a new /dev/ttyACM number).
//
// Not RT code: a plain thread; for tests and tools.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace rack::sims {

class NmeaGpsSim {
 public:
  struct Config {
    double latitude_deg = 52.3826;  // start (Hannover, Appelstrasse)
    double longitude_deg = 9.7177;
    double altitude_m = 55.0;
    double speed_mps = 1.0;           // over ground
    double course_deg = 90.0;         // clockwise from true north
    int64_t period_ns = 100'000'000;  // 10 Hz
    uint8_t satellites = 9;
    double hdop = 0.9;
    std::string link;  // symlink to the pty slave ("" = none)
    const char* talker = "GP";
  };
  enum class Fault : uint8_t { kNone, kBadChecksum, kGarbage, kSilent };

  explicit NmeaGpsSim(Config config);
  ~NmeaGpsSim();
  NmeaGpsSim(const NmeaGpsSim&) = delete;
  NmeaGpsSim& operator=(const NmeaGpsSim&) = delete;

  // Opens the pty and starts writing. Throws std::system_error.
  void start();
  void stop();
  // The device path a driver opens: the symlink if configured, else the pty slave.
  [[nodiscard]] std::string device() const;
  void set_fault(Fault f) { fault_.store(f); }
  // Closes the pty master (the driver reads EIO: the device went away).
  void unplug();
  // A new pty; the symlink moves to it.
  void plug();
  [[nodiscard]] uint64_t epochs_sent() const { return epochs_.load(); }

  // One epoch's sentences (CR LF terminated) for a position; public for tests.
  static std::string sentences(const Config& c, double lat, double lon, int64_t utc_ns);

 private:
  void run();
  void open_pty();
  void close_pty();

  Config config_;
  mutable std::mutex mutex_;  // guards master_/slave_path_ against plug/unplug
  int master_ = -1;
  int slave_keep_ = -1;  // keeps the slave side open so writes do not fail before a reader
  std::string slave_path_;
  std::atomic<Fault> fault_{Fault::kNone};
  std::atomic<bool> stop_{false};
  std::atomic<uint64_t> epochs_{0};
  std::thread thread_;
};

}  // namespace rack::sims
