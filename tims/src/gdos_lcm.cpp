#include "rack/tims/gdos_lcm.h"

#include <poll.h>
#include <unistd.h>

#include <lcm/lcm-cpp.hpp>
#include <atomic>
#include <mutex>
#include <stdexcept>
#include <vector>

#include "lcm_receive.h"
#include "lcm_wire.h"
#include "rack/rt/clock.h"
#include "rack/tims/link_auth.h"
#include "rack_lcm/gdos_batch.hpp"
#include "rack_lcm/gdos_listener.hpp"
#include "rack_lcm/host_announce.hpp"

namespace rack::tims {

namespace {
// The TiMS transport's announcement channel (lcm_transport.cpp): component names.
constexpr const char* kAnnounceChannel = "TIMS_ANNOUNCE";

std::string join_error(const std::string& url) {
  return "cannot join the LCM network '" + url +
         "' for GDOS (a network namespace needs 'ip link set lo up' and a multicast route: "
         "ip route add 224.0.0.0/4 dev lo)";
}

// Per-record overhead of gdos_record on the wire (fixed fields + string lengths).
constexpr std::size_t kRecordOverhead = 8 + 8 + 4 + 4 + 1 + 4 + 4 + 2;
}  // namespace

// ---- publisher ----

struct GdosPublisher::Impl {
  explicit Impl(GdosPublisherConfig c) : config(std::move(c)), lcm(config.url) {
    if (!config.key_file.empty()) {
      keys = std::make_unique<KeyRing>(config.key_file);
      int64_t sender = 0;
      randombytes(sender);
      signer = std::make_unique<LinkSigner>(*keys, sender);
    }
  }
  static void randombytes(int64_t& v) {
    // Any distinct value per process will do (the MAC makes it unforgeable).
    v = rt::monotonic_ns() ^ (static_cast<int64_t>(getpid()) << 40) ^ rt::host_time_ns();
    if (v == 0) v = 1;
  }
  GdosPublisherConfig config;
  lcm::LCM lcm;
  std::unique_ptr<KeyRing> keys;
  std::unique_ptr<LinkSigner> signer;
  std::vector<uint8_t> scratch;
  int64_t next_key_check_ns = 0;
  rack_lcm::gdos_batch batch;
  std::size_t batch_bytes = 0;
  int64_t last_listener_ns = INT64_MIN / 2;
  // Written by the publishing thread, read by any (relaxed: statistics).
  std::atomic<uint64_t> records{0}, batches{0}, publish_errors{0}, refused{0}, socket_refused{0};
  // Listener announcements: on a udpm network read from an own socket (lcm_receive.h),
  // opened at the first listener_present(); elsewhere (memq://) through LCM. Either
  // way decoded by lcm_wire.h: LCM's reassembly and lcm-gen's decoder never see them.
  std::unique_ptr<lcm_rx::LcmSocketReader> reader;
  bool subscribed = false;

  void on_listener_bytes(const uint8_t* d, std::size_t size) {
    rack_lcm::gdos_listener l;
    std::string why;
    if (wire_lcm::decode(d, size, l, why) < 0) {
      refused.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    last_listener_ns = rt::monotonic_ns();
  }
  void on_listener(const lcm::ReceiveBuffer* rbuf, const std::string&) {
    on_listener_bytes(static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
  }
  void listen() {
    if (reader || subscribed) return;
    if (const auto u = lcm_rx::parse_udpm(config.url)) {
      // A listener announcement is a few dozen bytes: 1 KB of each datagram is read.
      reader = std::make_unique<lcm_rx::LcmSocketReader>(config.url, *u, 1024);
    } else {
      lcm.subscribe(kGdosListenerChannel, &Impl::on_listener, this);
      subscribed = true;
    }
  }
};

GdosPublisher::GdosPublisher(GdosPublisherConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {
  if (!impl_->lcm.good()) throw std::runtime_error(join_error(impl_->config.url));
  impl_->batch.host = impl_->config.host;
  impl_->batch.pid = impl_->config.pid;
}

GdosPublisher::~GdosPublisher() = default;

void GdosPublisher::add(uint32_t source, std::string_view name, uint8_t level, int64_t time_ns, uint64_t sequence,
                        uint32_t dropped_before, std::string_view text) {
  const std::size_t bytes = kRecordOverhead + name.size() + text.size();
  if (!impl_->batch.records.empty() && impl_->batch_bytes + bytes > impl_->config.max_batch_bytes) flush();
  rack_lcm::gdos_record r;
  r.time_ns = time_ns;
  r.sequence = static_cast<int64_t>(sequence);
  r.source = static_cast<int32_t>(source);
  r.name = std::string(name);
  r.level = static_cast<int8_t>(level);
  r.dropped_before = static_cast<int32_t>(dropped_before);
  r.text = std::string(text);
  impl_->batch.records.push_back(std::move(r));
  impl_->batch_bytes += bytes;
}

void GdosPublisher::flush() {
  auto& b = impl_->batch;
  if (b.records.empty()) return;
  b.count = static_cast<int32_t>(b.records.size());
  b.time_ns = rt::host_time_ns();
  int rc = 0;
  if (impl_->signer) {
    Impl& m = *impl_;
    if (rt::monotonic_ns() >= m.next_key_check_ns) {  // rotation: the TiMS transport says so in the log
      (void)m.keys->check_reload();
      m.next_key_check_ns = rt::monotonic_ns() + rt::kNsPerSec;
    }
    const int size = b.getEncodedSize();
    m.scratch.resize(static_cast<std::size_t>(size) + kAuthTrailerBytes);
    rc = b.encode(m.scratch.data(), 0, size) == size ? 0 : -1;
    if (rc == 0) {
      m.signer->sign(m.config.channel, m.scratch.data(), static_cast<std::size_t>(size), m.scratch.data() + size,
                     rt::host_time_ns());
      rc = m.lcm.publish(m.config.channel, m.scratch.data(), static_cast<unsigned>(m.scratch.size()));
    }
  } else {
    rc = impl_->lcm.publish(impl_->config.channel, &b);
  }
  if (rc != 0) {
    impl_->publish_errors.fetch_add(1, std::memory_order_relaxed);
  } else {
    impl_->batches.fetch_add(1, std::memory_order_relaxed);
    impl_->records.fetch_add(b.records.size(), std::memory_order_relaxed);
  }
  b.records.clear();
  impl_->batch_bytes = 0;
}

bool GdosPublisher::listener_present(int64_t within_ns) {
  Impl& m = *impl_;
  try {
    m.listen();
  } catch (const std::exception&) {
    // Cannot open the socket (descriptors exhausted): no listener is seen, the log
    // goes to stderr; counted, tried again next time.
    m.refused.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  if (m.reader) {
    // Non-blocking: what has arrived, bounded per call (the bus may carry TiMS traffic).
    lcm_rx::ReadDatagram rd;
    for (int i = 0; i < 1024 && m.reader->read(rd, {}, 64); ++i) {
      if (rd.datagram.channel != kGdosListenerChannel) continue;
      if (rd.truncated) {
        m.refused.fetch_add(1, std::memory_order_relaxed);
        continue;
      }
      m.on_listener_bytes(rd.datagram.payload, rd.datagram.payload_size);
    }
    const auto& rc = m.reader->counters();
    m.socket_refused.store(rc.fragments + rc.bad_framing, std::memory_order_relaxed);
  } else {
    pollfd pfd{m.lcm.getFileno(), POLLIN, 0};
    // Non-blocking: only what has arrived. handle() reads one datagram.
    for (int i = 0; i < 64 && poll(&pfd, 1, 0) > 0 && (pfd.revents & POLLIN) != 0; ++i) {
      m.lcm.handle();
      pfd.revents = 0;
    }
  }
  return rt::monotonic_ns() - m.last_listener_ns <= within_ns;
}

GdosPublisherCounters GdosPublisher::counters() const noexcept {
  GdosPublisherCounters c;
  c.records = impl_->records.load(std::memory_order_relaxed);
  c.batches = impl_->batches.load(std::memory_order_relaxed);
  c.publish_errors = impl_->publish_errors.load(std::memory_order_relaxed);
  c.refused = impl_->refused.load(std::memory_order_relaxed) + impl_->socket_refused.load(std::memory_order_relaxed);
  return c;
}
const std::string& GdosPublisher::url() const noexcept { return impl_->config.url; }

// ---- subscriber ----

struct GdosSubscriber::Impl {
  Impl(const std::string& u, std::string c, bool a, std::string n, const std::string& key_file)
      : url(u), channel(std::move(c)), announce(a), name(std::move(n)), lcm(u), warn([this](const std::string& line) {
          warnings += line + "\n";
        }) {
    if (!key_file.empty()) {
      keys = std::make_unique<KeyRing>(key_file);
      verifier = std::make_unique<LinkVerifier>(*keys, kDefaultReplayWindowNs);
    }
  }
  std::unique_ptr<KeyRing> keys;
  std::unique_ptr<LinkVerifier> verifier;
  int64_t next_key_check_ns = 0;
  bool warned_unverified = false;

  // With a key: verifies and strips the trailer (false: dropped, counted, warned at
  // most once a second). Without: passes everything on.
  bool authentic(std::string_view ch, const uint8_t* d, std::size_t& size) {
    if (!verifier) return true;
    const int64_t now = rt::monotonic_ns();
    if (now >= next_key_check_ns) {
      const std::string m = keys->check_reload();
      if (!m.empty()) warnings += "gdos: " + m + "\n";
      next_key_check_ns = now + rt::kNsPerSec;
    }
    const AuthResult r = verifier->verify(ch, d, size, rt::host_time_ns(), now);
    if (r == AuthResult::kOk) {
      size -= kAuthTrailerBytes;
      return true;
    }
    ++(is_replay(r) ? counters.replayed : counters.auth_failed);
    warn("auth", [&] { return "gdos: dropped a message on '" + std::string(ch) + "' (" + url + "): " + describe(r); });
    return false;
  }
  std::string url;
  std::string channel;
  bool announce;
  std::string name;
  lcm::LCM lcm;  // publishes the listener announcements; receives only on memq:// and the like
  // udpm networks: our own bounds-checked reader (lcm_receive.h); LCM's receive path
  // (its fragment reassembly) never sees the network.
  std::unique_ptr<lcm_rx::LcmSocketReader> reader;
  int64_t next_announce_ns = 0;
  std::map<uint32_t, std::string> names;          // from TIMS_ANNOUNCE
  std::map<std::string, uint64_t> last_sequence;  // per host/pid
  GdosSubscriberCounters counters;
  std::string warnings;
  lcm_rx::RateLimitedWarn warn;  // at most one line per kind per second into `warnings`
  const std::function<void(const GdosRecord&)>* sink = nullptr;
  std::size_t handled = 0;

  // Bounds on what hostile traffic could grow (far above a real fleet).
  static constexpr std::size_t kMaxNames = 65536;
  static constexpr std::size_t kMaxSenders = 4096;

  // One LCM message (after the framing), from either path.
  void on_message(std::string_view ch, const uint8_t* d, std::size_t size) {
    if (ch == channel) return on_batch(ch, d, size);
    if (ch == kAnnounceChannel) on_announce(ch, d, size);
  }

  // One datagram in LCM's framing (own socket, or handle_datagram()).
  void on_datagram(const uint8_t* d, std::size_t size) {
    const wire_lcm::LcmDatagram g = wire_lcm::parse_datagram(d, size);
    if (g.kind == wire_lcm::LcmDatagram::kFragment) {
      ++counters.lcm_fragments;
      return refused("fragment", "LCM fragment of " + std::to_string(size) + " bytes refused");
    }
    if (g.kind != wire_lcm::LcmDatagram::kMessage) {
      ++counters.bad_datagrams;
      return refused("framing", std::to_string(size) + "-byte datagram: " + g.why);
    }
    on_message(g.channel, g.payload, g.payload_size);
  }
  void refused(const char* kind, const std::string& why) {
    warn(kind, [&] { return "gdos: dropped on " + url + ": " + why; });
  }

  void on_batch(std::string_view ch, const uint8_t* data, std::size_t full_size) {
    std::size_t size = full_size;
    if (!authentic(ch, data, size)) return;
    rack_lcm::gdos_batch b;
    std::string why;
    const int used = wire_lcm::decode(data, size, b, why);
    if (!verifier && !warned_unverified && used > 0 && looks_signed(data, size) &&
        static_cast<std::size_t>(used) + kAuthTrailerBytes == size) {
      warned_unverified = true;
      warnings += "gdos: the records on '" + std::string(ch) +
                  "' are signed: give --key-file to verify them (shown unverified)\n";
    }
    if (used < 0 || b.count < 0 || static_cast<std::size_t>(b.count) != b.records.size()) {
      ++counters.malformed;
      return warn("malformed", [&] {
        return "gdos: dropped a malformed batch of " + std::to_string(full_size) + " bytes on '" + std::string(ch) +
               "' (" + url + "): " + why;
      });
    }
    ++counters.batches;
    const std::string key = b.host + "/" + std::to_string(b.pid);
    if (last_sequence.size() >= kMaxSenders && last_sequence.count(key) == 0) last_sequence.clear();
    for (const auto& r : b.records) {
      const auto seq = static_cast<uint64_t>(r.sequence);
      auto it = last_sequence.find(key);
      if (it != last_sequence.end() && seq > it->second + 1) {
        const uint64_t lost = seq - it->second - 1;
        counters.lost += lost;
        warn("lost " + key, [&] {
          return "gdos: " + std::to_string(lost) + " record(s) of " + b.host + " (pid " + std::to_string(b.pid) +
                 ") lost on the network";
        });
      }
      last_sequence[key] = seq;
      GdosRecord out;
      out.host = b.host;
      out.pid = b.pid;
      out.source = static_cast<uint32_t>(r.source);
      out.name = r.name;
      out.level = static_cast<uint8_t>(r.level);
      out.time_ns = r.time_ns;
      out.sequence = seq;
      out.dropped_before = static_cast<uint32_t>(r.dropped_before);
      out.text = r.text;
      ++counters.records;
      ++handled;
      if (sink != nullptr) (*sink)(out);
    }
  }

  void on_announce(std::string_view ch, const uint8_t* data, std::size_t full_size) {
    std::size_t size = full_size;
    if (!authentic(ch, data, size)) return;
    rack_lcm::host_announce a;
    std::string why;
    // Counted, not warned: another version of the announcement (a newer rackd) is not
    // an error here; names are a convenience, the records carry them too.
    if (wire_lcm::decode(data, size, a, why) < 0) {
      ++counters.bad_announcements;
      return;
    }
    if (names.size() + a.components.size() > kMaxNames) names.clear();
    for (const auto& c : a.components) names[static_cast<uint32_t>(c.address)] = c.name;
  }

  void send_announcement() {
    rack_lcm::gdos_listener l;
    l.time_ns = rt::host_time_ns();
    l.name = name;
    l.pid = static_cast<int32_t>(getpid());
    (void)lcm.publish(kGdosListenerChannel, &l);
  }

  // Handles what is waiting on the socket (or in LCM's queue), bounded per call.
  void drain() {
    if (reader) {
      lcm_rx::ReadDatagram rd;
      const auto on_refused = [&](const char* kind, const std::string& why) { refused(kind, why); };
      for (int i = 0; i < 4096 && reader->read(rd, on_refused); ++i) {
        if (rd.truncated) continue;  // cannot happen: the buffer holds any UDP datagram
        on_message(rd.datagram.channel, rd.datagram.payload, rd.datagram.payload_size);
      }
      counters.lcm_fragments = reader->counters().fragments;
      counters.bad_datagrams = reader->counters().bad_framing;
      return;
    }
    pollfd pfd{lcm.getFileno(), POLLIN, 0};
    for (int i = 0; i < 4096 && ::poll(&pfd, 1, 0) > 0 && (pfd.revents & POLLIN) != 0; ++i) {
      pfd.revents = 0;
      lcm.handle();
    }
  }
  void on_lcm(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    on_message(ch, static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
  }
};

GdosSubscriber::GdosSubscriber(const std::string& url, const std::string& channel, bool announce, std::string name,
                               const std::string& key_file)
    : impl_(std::make_unique<Impl>(url, channel, announce, std::move(name), key_file)) {
  if (!impl_->lcm.good()) throw std::runtime_error(join_error(url));
  if (const auto u = lcm_rx::parse_udpm(url)) {
    impl_->reader = std::make_unique<lcm_rx::LcmSocketReader>(url, *u, 65536);
  } else {
    // Raw handlers: decoded by lcm_wire.h, a batch that does not decode is counted.
    impl_->lcm.subscribe(channel, &Impl::on_lcm, impl_.get())->setQueueCapacity(4096);
    impl_->lcm.subscribe(kAnnounceChannel, &Impl::on_lcm, impl_.get())->setQueueCapacity(256);
  }
}

GdosSubscriber::~GdosSubscriber() = default;

std::size_t GdosSubscriber::poll(int timeout_ms, const std::function<void(const GdosRecord&)>& sink) {
  impl_->sink = &sink;
  impl_->handled = 0;
  const int64_t end = rt::monotonic_ns() + static_cast<int64_t>(timeout_ms) * rt::kNsPerMs;
  pollfd pfd{impl_->reader ? impl_->reader->fd() : impl_->lcm.getFileno(), POLLIN, 0};
  for (;;) {
    const int64_t now = rt::monotonic_ns();
    if (impl_->announce && now >= impl_->next_announce_ns) {
      impl_->send_announcement();
      impl_->next_announce_ns = now + rt::kNsPerSec;
    }
    int64_t left_ms = (end - now) / rt::kNsPerMs;
    if (left_ms < 0) left_ms = 0;
    if (impl_->announce && left_ms > 1000) left_ms = 1000;
    pfd.revents = 0;
    // poll(), not LCM's handleTimeout() (select() aborts above fd 1023).
    const int rc = ::poll(&pfd, 1, static_cast<int>(left_ms));
    if (rc > 0 && (pfd.revents & POLLIN) != 0) impl_->drain();
    if (impl_->handled > 0 || rt::monotonic_ns() >= end) break;
  }
  impl_->sink = nullptr;
  return impl_->handled;
}

void GdosSubscriber::handle_datagram(const uint8_t* data, std::size_t size,
                                     const std::function<void(const GdosRecord&)>& sink) {
  impl_->sink = &sink;
  impl_->on_datagram(data, size);
  impl_->sink = nullptr;
}

std::string GdosSubscriber::announced_name(uint32_t address) const {
  const auto it = impl_->names.find(address & 0xFFFFFF00u);
  return it == impl_->names.end() ? std::string() : it->second;
}

GdosSubscriberCounters GdosSubscriber::counters() const noexcept { return impl_->counters; }

std::string GdosSubscriber::take_warnings() {
  std::string w;
  w.swap(impl_->warnings);
  return w;
}

}  // namespace rack::tims
