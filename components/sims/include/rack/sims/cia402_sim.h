// Cia402DriveSim: one or more CANopen CiA 402 servo drives on a CAN-frame socket, for
// developing and testing the CAN drivers without hardware (tests, and
// `rack-devsim cia402` on the command line).
//
// Implements what RACK-RT's drivers use (rack/devices/canopen.h): NMT (start, stop,
// pre-operational, reset node with boot-up message), expedited SDO read/write of the
// objects listed there (unknown objects are aborted with 0x06020000), the CiA 402
// power state machine driven by the controlword, profile velocity mode (ramps to the
// target velocity with the profile acceleration/deceleration) and profile position
// mode (moves to a target position at the profile velocity, "target reached" bit),
// RPDO2 (profile velocity, for profile position moves), TPDO1/TPDO2 on every SYNC while operational, and heartbeats at the configured
// producer time (0x1017).
//
// Transports: attach(fd) serves a socket carrying one struct can_frame per packet
// (one end of a socketpair; a CAN_RAW socket bound to vcan0 also works);
// listen_unix(path) accepts CanPort::open_unix() clients one at a time.
// Faults for tests: a node can fall silent (a drive that lost power: no heartbeat,
// no answers), and the simulator can send malformed packets.
//
// Not RT code: a plain thread with a 1 ms tick; for tests and tools.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace rack::sims {

class Cia402DriveSim {
 public:
  struct Config {
    std::vector<uint8_t> nodes{1, 2};
    int64_t tick_ns = 1'000'000;
  };
  struct DriveState {
    uint8_t nmt = 0;  // canopen::kState*
    uint16_t statusword = 0;
    int8_t mode = 0;
    int32_t target_velocity = 0;  // counts/s
    int32_t target_position = 0;  // counts (the last one written)
    int32_t active_target = 0;    // counts (the set-point being approached)
    double velocity = 0.0;        // counts/s
    double position = 0.0;        // counts
    uint16_t heartbeat_ms = 0;
    uint64_t rpdos = 0, syncs = 0, sdos = 0;
  };

  explicit Cia402DriveSim(Config config);
  ~Cia402DriveSim();
  Cia402DriveSim(const Cia402DriveSim&) = delete;
  Cia402DriveSim& operator=(const Cia402DriveSim&) = delete;

  void attach(int fd);  // takes ownership; call before start()
  // Listens on an AF_UNIX SOCK_SEQPACKET path (replacing a stale socket file). Throws.
  void listen_unix(const std::string& path);
  void start();
  void stop();

  void set_silent(uint8_t node, bool silent);
  // Holds the drive in NMT `state` (canopen::kState*; its heartbeats say so) and makes
  // it ignore NMT commands, as a drive in local control or after an internal reset;
  // release() gives NMT back to the master (the state stays until it sends one).
  void hold_nmt(uint8_t node, uint8_t state);
  void release_nmt(uint8_t node);
  // Sends `count` malformed packets (short packets, oversized dlc) and frames with
  // ids nobody uses, interleaved with the normal traffic.
  void inject_garbage(int count) { garbage_.fetch_add(count); }
  // Sends a controller error frame reporting bus-off (as a CAN controller's driver
  // does), then, after `restart_after_ns`, one reporting the restart (restart-ms).
  void inject_bus_off(int64_t restart_after_ns) { bus_off_.store(restart_after_ns); }
  // Closes the current client connection (a cable pulled); listen_unix keeps accepting.
  void drop_client();
  [[nodiscard]] DriveState state(uint8_t node) const;
  [[nodiscard]] bool has_client() const;
  // For tests and tests/fuzz/fuzz_devsim.cpp, without start(): one packet from the bus
  // as run() receives it (answers go to the attached socket, if any), and one tick of
  // the drives' motion, dt_s after the last, at monotonic time now_ns (heartbeats).
  void receive(const uint8_t* data, std::size_t len);
  void advance(double dt_s, int64_t now_ns);

 private:
  struct Drive {
    uint8_t id = 0;
    DriveState s;
    bool silent = false;
    bool nmt_held = false;
    int64_t next_heartbeat_ns = 0;
    uint32_t acceleration = 10000;  // counts/s^2
    uint32_t deceleration = 10000;
    uint32_t profile_velocity = 1000;
    uint8_t tpdo_type[2] = {1, 1};
    bool new_setpoint = false;
    bool position_active = false;
  };
  void run();
  void handle(const uint8_t* data, std::size_t len);
  void handle_sdo(Drive& d, const uint8_t* data);
  void control(Drive& d, uint16_t cw);
  void tick(double dt, int64_t now);
  void send(uint32_t id, const uint8_t* data, uint8_t len);
  void send_garbage();
  Drive* find(uint8_t id);

  Config config_;
  mutable std::mutex mutex_;
  std::vector<Drive> drives_;
  int fd_ = -1;
  int listen_fd_ = -1;
  std::string listen_path_;
  std::atomic<int> garbage_{0};
  std::atomic<int64_t> bus_off_{-1};  // >= 0: send bus-off now, restart after this long
  int64_t restart_at_ns_ = -1;
  bool silenced_by_bus_off_ = false;
  std::atomic<bool> stop_{false};
  std::atomic<bool> drop_{false};
  std::thread thread_;
};

}  // namespace rack::sims
