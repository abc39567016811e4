// Receiving LCM traffic without LCM (internal to tims): every RACK-RT receiver of a
// udpm:// network (the TiMS transport, the GDOS publisher's listener check, the GDOS
// subscriber of the `gdos` viewer) reads the datagrams from a socket of its own and
// parses LCM's framing with bounds-checked code (lcm_wire.h). LCM 1.3.1's receive
// path reassembles fragments from unchecked fields (two datagrams segfaulted the
// viewer) and hands lcm-gen's throwing decoders whatever arrives; here fragments are
// refused and counted, and each receiver decodes with the total decoders of
// lcm_wire.h. Publishing still goes through LCM (lcm-logger and lcm-logplayer see
// the same datagrams).
//
// Real-time contract: nothing here is RT-safe (set-up and non-RT receive threads).
// Thread-safety: one thread per LcmSocketReader; RateLimitedWarn from any thread.
#pragma once

#include <netinet/in.h>

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "lcm_wire.h"
#include "rack/rt/clock.h"

namespace rack::tims::lcm_rx {

// An LCM udpm URL: udpm://GROUP:PORT?ttl=N&recv_buf_size=BYTES (LCM's defaults).
struct UdpmUrl {
  in_addr group{};
  uint16_t port = 7667;
  int recv_buf_size = 0;
};
// nullopt: not a udpm URL (memq://, file://: those receive through LCM) or malformed.
[[nodiscard]] std::optional<UdpmUrl> parse_udpm(const std::string& url);

// The receive side of a udpm network as LCM sets it up: any address, the port shared
// with every other member on this machine (SO_REUSEADDR), the group joined, the
// buffer size of the URL (capped by net.core.rmem_max). Non-blocking, close-on-exec.
// Throws std::runtime_error naming the URL, the failed call and errno.
[[nodiscard]] int open_udpm_socket(const std::string& url, const UdpmUrl& u);

// At most one line per second per kind; the rest are counted and summarised in the
// next line of that kind ("(N more like it suppressed)").
class RateLimitedWarn {
 public:
  explicit RateLimitedWarn(std::function<void(const std::string&)> sink) : sink_(std::move(sink)) {}
  template <typename MakeText>
  void operator()(const std::string& kind, MakeText make_text) {
    std::lock_guard lock(mutex_);
    const int64_t now = rt::monotonic_ns();
    auto& s = state_[kind];
    if (now - s.last_ns < kIntervalNs) {
      ++s.suppressed;
      return;
    }
    std::string line = make_text();
    if (s.suppressed > 0) line += " (" + std::to_string(s.suppressed) + " more like it suppressed)";
    s.suppressed = 0;
    s.last_ns = now;
    if (state_.size() > kMaxKinds) state_.clear();  // kinds are few; bounded anyway
    sink_(line);
  }

 private:
  static constexpr int64_t kIntervalNs = 1'000'000'000;
  static constexpr std::size_t kMaxKinds = 1024;
  struct State {
    int64_t last_ns = INT64_MIN / 2;
    uint64_t suppressed = 0;
  };
  std::function<void(const std::string&)> sink_;
  std::mutex mutex_;
  std::map<std::string, State> state_;
};

struct LcmReceiveCounters {
  uint64_t datagrams = 0;    // read from the socket
  uint64_t bad_framing = 0;  // not LCM: short, wrong magic, channel name unterminated or too long
  uint64_t fragments = 0;    // LCM fragments, refused (RACK-RT never sends them)
};

// One datagram read by LcmSocketReader.
struct ReadDatagram {
  wire_lcm::LcmDatagram datagram;  // payload points into the reader's buffer (valid until the next read)
  std::size_t size = 0;            // the datagram's real size
  bool truncated = false;          // larger than the reader's buffer: the payload is cut short
};

// A udpm network's datagrams, read from an own socket. Fragments and datagrams that are
// not LCM are counted (counters()) and not returned; `refused` (optional) hears why.
class LcmSocketReader {
 public:
  // `buffer_bytes`: the largest datagram read whole (65536: any UDP datagram); a larger
  // one is returned truncated (a receiver that only needs small messages, such as the
  // GDOS publisher's listener check, reads a few hundred bytes of each).
  LcmSocketReader(const std::string& url, const UdpmUrl& u, std::size_t buffer_bytes);
  ~LcmSocketReader();
  LcmSocketReader(const LcmSocketReader&) = delete;
  LcmSocketReader& operator=(const LcmSocketReader&) = delete;

  [[nodiscard]] int fd() const { return fd_; }
  // Reads datagrams (non-blocking) until one is a whole LCM message (true, `out` set)
  // or none is waiting (false). At most `max_refused` refused datagrams are read in
  // one call, so a flood of them cannot keep the caller here.
  bool read(ReadDatagram& out, const std::function<void(const char* kind, const std::string& why)>& refused = {},
            int max_refused = 256);
  [[nodiscard]] const LcmReceiveCounters& counters() const { return counters_; }

 private:
  int fd_ = -1;
  std::vector<uint8_t> buffer_;
  LcmReceiveCounters counters_;
};

}  // namespace rack::tims::lcm_rx
