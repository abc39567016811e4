// Raw UDP multicast datagrams to a private LCM bus (LcmBus's port, LCM's default
// group), in LCM's own framing or in none: the tests that play a broken device or an
// attacker on the bus (hostile_net_test, tims_input_test, tools_fanout_test) write
// what real LCM would never send, field by field.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace rack::test {

using Bytes = std::vector<uint8_t>;

// Big-endian fields, as LCM's framing and lcm-gen's encoders write them.
inline void put32(Bytes& d, uint32_t v) {
  for (int i = 3; i >= 0; --i) d.push_back(static_cast<uint8_t>(v >> (8 * i)));
}
inline void put64(Bytes& d, uint64_t v) {
  for (int i = 7; i >= 0; --i) d.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

class RawLcm {
 public:
  explicit RawLcm(int port) {
    fd_ = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error("socket");
    const unsigned char ttl = 0, loop = 1;  // stays on this machine, reaches our own stack
    setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl);
    setsockopt(fd_, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop);
    to_.sin_family = AF_INET;
    to_.sin_port = htons(static_cast<uint16_t>(port));
    inet_pton(AF_INET, "239.255.76.67", &to_.sin_addr);
  }
  ~RawLcm() { close(fd_); }
  RawLcm(const RawLcm&) = delete;
  RawLcm& operator=(const RawLcm&) = delete;

  // "LC02", sequence number, channel, NUL, payload (lcm_udpm.c).
  void send(const std::string& channel, const Bytes& payload) {
    Bytes d;
    put32(d, 0x4c433032u);
    put32(d, seq_++);
    d.insert(d.end(), channel.begin(), channel.end());
    d.push_back(0);
    d.insert(d.end(), payload.begin(), payload.end());
    send_raw(d);
  }
  // "LC03": a fragment of a message of `total` bytes (lcm_udpm.c's layout), with
  // whatever fields are given; the first fragment carries the channel.
  void send_fragment(uint32_t msg_seq, uint32_t total, uint32_t offset, uint16_t number, uint16_t count,
                     const std::string& channel, std::size_t bytes) {
    Bytes d;
    put32(d, 0x4c433033u);
    put32(d, msg_seq);
    put32(d, total);
    put32(d, offset);
    d.push_back(static_cast<uint8_t>(number >> 8));
    d.push_back(static_cast<uint8_t>(number));
    d.push_back(static_cast<uint8_t>(count >> 8));
    d.push_back(static_cast<uint8_t>(count));
    if (number == 0) {
      d.insert(d.end(), channel.begin(), channel.end());
      d.push_back(0);
    }
    d.resize(d.size() + bytes, 0xA5);
    send_raw(d);
  }
  // The bytes as they are, no framing.
  void send_raw(const Bytes& d) {
    (void)sendto(fd_, d.data(), d.size(), 0, reinterpret_cast<const sockaddr*>(&to_), sizeof to_);
  }

 private:
  int fd_ = -1;
  sockaddr_in to_{};
  uint32_t seq_ = 0;
};

}  // namespace rack::test
