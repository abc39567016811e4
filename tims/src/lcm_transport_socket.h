// One network's sockets (internal to tims): LCM for publishing (so that lcm-logger and
// lcm-logplayer see and replay the same datagrams), and for receiving, on a udpm://
// network, a multicast socket of our own read in LCM's framing instead of through
// LCM 1.3's receive thread and notify pipe (two thread hand-offs less per message;
// LCM never opens its receive socket: there is no subscription). On other URLs
// (memq://, file://) LCM receives our three channels and hands each payload to a
// PayloadHandler.
//
// Real-time contract: nothing here is RT-safe. Thread-safety: publish() under the
// network's publish lock; the reads and handle_lcm() on its receive thread only.
#pragma once

#include <lcm/lcm-cpp.hpp>
#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "rack/tims/lcm_transport.h"

namespace rack::tims {

// Where LCM-received payloads go (networks that LCM receives).
class PayloadHandler {
 public:
  virtual ~PayloadHandler() = default;
  virtual void on_payload(std::string_view channel, const uint8_t* d, std::size_t size) = 0;
};

class LcmSocket {
 public:
  // Datagrams above this are looked at (peek) before they are read.
  static constexpr std::size_t kPeekBytes = 256;

  // Joins `config.url`. Throws std::runtime_error naming the network or URL (with the
  // hint for network namespaces) when the URL is invalid or cannot be joined.
  LcmSocket(const NetworkConfig& config, PayloadHandler& handler);
  ~LcmSocket();
  LcmSocket(const LcmSocket&) = delete;
  LcmSocket& operator=(const LcmSocket&) = delete;

  // Publishing (LCM). 0 on success.
  int publish(const char* channel, const uint8_t* buf, std::size_t len);
  template <typename T>
  int publish(const char* channel, const T& m) {
    return lcm_->publish(channel, &m);
  }

  // What the receive thread polls for input.
  [[nodiscard]] int poll_fd() const;
  // True: this socket reads datagrams itself (read/peek/discard/read_split); false:
  // LCM receives, and handle_lcm() hands one message to the PayloadHandler.
  [[nodiscard]] bool own_socket() const noexcept { return fd_ >= 0; }
  void handle_lcm();

  // Our own socket, non-blocking; each returns the datagram's real size (MSG_TRUNC),
  // or -1 when none is waiting. read(): the next datagram into buffer(); peek(): its
  // first kPeekBytes into buffer(), left in the socket; discard(): drops it unread;
  // read_split(): its first `head` bytes into buffer() and the next `tail_bytes` to
  // `tail` (a chunk straight into its reassembly slot).
  ssize_t read();
  ssize_t peek();
  void discard();
  ssize_t read_split(std::size_t head, std::byte* tail, std::size_t tail_bytes);
  [[nodiscard]] const uint8_t* buffer() const noexcept { return datagram_.data(); }
  [[nodiscard]] std::size_t capacity() const noexcept { return datagram_.size(); }
  // Whether the last datagram read or peeked was above kPeekBytes (the next is then
  // looked at first: large ones come in bursts).
  [[nodiscard]] bool last_was_large() const noexcept { return last_large_; }

 private:
  void on_lcm(const lcm::ReceiveBuffer* rbuf, const std::string& channel);

  PayloadHandler& handler_;
  std::unique_ptr<lcm::LCM> lcm_;
  int fd_ = -1;  // our own udpm socket; -1: LCM receives
  std::vector<uint8_t> datagram_;
  bool last_large_ = false;
};

}  // namespace rack::tims
