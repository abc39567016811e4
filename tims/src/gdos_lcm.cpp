#include "rack/tims/gdos_lcm.h"

#include <poll.h>
#include <unistd.h>

#include <lcm/lcm-cpp.hpp>
#include <atomic>
#include <mutex>
#include <stdexcept>
#include <vector>

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
  std::atomic<uint64_t> records{0}, batches{0}, publish_errors{0};

  void on_listener(const lcm::ReceiveBuffer*, const std::string&, const rack_lcm::gdos_listener*) {
    last_listener_ns = rt::monotonic_ns();
  }
};

GdosPublisher::GdosPublisher(GdosPublisherConfig config) : impl_(std::make_unique<Impl>(std::move(config))) {
  if (!impl_->lcm.good()) throw std::runtime_error(join_error(impl_->config.url));
  impl_->lcm.subscribe(kGdosListenerChannel, &Impl::on_listener, impl_.get());
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
      m.signer->sign(m.config.channel, m.scratch.data(), static_cast<std::size_t>(size),
                     m.scratch.data() + size, rt::host_time_ns());
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
  pollfd pfd{impl_->lcm.getFileno(), POLLIN, 0};
  // Non-blocking: only what has arrived. handle() reads one datagram.
  for (int i = 0; i < 64 && poll(&pfd, 1, 0) > 0 && (pfd.revents & POLLIN) != 0; ++i) {
    impl_->lcm.handle();
    pfd.revents = 0;
  }
  return rt::monotonic_ns() - impl_->last_listener_ns <= within_ns;
}

GdosPublisherCounters GdosPublisher::counters() const noexcept {
  GdosPublisherCounters c;
  c.records = impl_->records.load(std::memory_order_relaxed);
  c.batches = impl_->batches.load(std::memory_order_relaxed);
  c.publish_errors = impl_->publish_errors.load(std::memory_order_relaxed);
  return c;
}
const std::string& GdosPublisher::url() const noexcept { return impl_->config.url; }

// ---- subscriber ----

struct GdosSubscriber::Impl {
  Impl(const std::string& u, std::string c, bool a, std::string n, const std::string& key_file)
      : url(u), channel(std::move(c)), announce(a), name(std::move(n)), lcm(u) {
    if (!key_file.empty()) {
      keys = std::make_unique<KeyRing>(key_file);
      verifier = std::make_unique<LinkVerifier>(*keys, kDefaultReplayWindowNs);
    }
  }
  std::unique_ptr<KeyRing> keys;
  std::unique_ptr<LinkVerifier> verifier;
  int64_t next_auth_warning_ns = 0;
  int64_t next_key_check_ns = 0;
  bool warned_unverified = false;

  // With a key: verifies and strips the trailer (false: dropped, counted, warned at
  // most once a second). Without: passes everything on.
  bool authentic(const std::string& ch, const uint8_t* d, std::size_t& size) {
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
    if (now >= next_auth_warning_ns) {
      warnings += "gdos: dropped a message on '" + ch + "' (" + url + "): " + describe(r) + "\n";
      next_auth_warning_ns = now + rt::kNsPerSec;
    }
    return false;
  }
  std::string url;
  std::string channel;
  bool announce;
  std::string name;
  lcm::LCM lcm;
  int64_t next_announce_ns = 0;
  std::map<uint32_t, std::string> names;  // from TIMS_ANNOUNCE
  std::map<std::string, uint64_t> last_sequence;  // per host/pid
  GdosSubscriberCounters counters;
  std::string warnings;
  const std::function<void(const GdosRecord&)>* sink = nullptr;
  std::size_t handled = 0;

  void on_batch(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    std::size_t size = rbuf->data_size;
    if (!authentic(ch, static_cast<const uint8_t*>(rbuf->data), size)) return;
    rack_lcm::gdos_batch b;
    const int used = b.decode(rbuf->data, 0, static_cast<int>(size));
    if (!verifier && !warned_unverified && used > 0 &&
        looks_signed(static_cast<const uint8_t*>(rbuf->data), size) &&
        static_cast<std::size_t>(used) + kAuthTrailerBytes == size) {
      warned_unverified = true;
      warnings += "gdos: the records on '" + ch + "' are signed: give --key-file to verify them (shown unverified)\n";
    }
    if (used < 0 || b.count < 0 ||
        static_cast<std::size_t>(b.count) != b.records.size()) {
      ++counters.malformed;
      warnings += "gdos: dropped a malformed batch of " + std::to_string(rbuf->data_size) + " bytes on '" + ch +
                  "' (" + url + ")\n";
      return;
    }
    ++counters.batches;
    const std::string key = b.host + "/" + std::to_string(b.pid);
    for (const auto& r : b.records) {
      const auto seq = static_cast<uint64_t>(r.sequence);
      auto it = last_sequence.find(key);
      if (it != last_sequence.end() && seq > it->second + 1) {
        const uint64_t lost = seq - it->second - 1;
        counters.lost += lost;
        warnings += "gdos: " + std::to_string(lost) + " record(s) of " + b.host + " (pid " + std::to_string(b.pid) +
                    ") lost on the network\n";
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

  void on_announce(const lcm::ReceiveBuffer* rbuf, const std::string& ch) {
    std::size_t size = rbuf->data_size;
    if (!authentic(ch, static_cast<const uint8_t*>(rbuf->data), size)) return;
    rack_lcm::host_announce a;
    // Another version of the announcement (a newer rackd) is not an error here:
    // names are a convenience; the records carry them too.
    if (a.decode(rbuf->data, 0, static_cast<int>(size)) < 0) return;
    for (const auto& c : a.components) names[static_cast<uint32_t>(c.address)] = c.name;
  }

  void send_announcement() {
    rack_lcm::gdos_listener l;
    l.time_ns = rt::host_time_ns();
    l.name = name;
    l.pid = static_cast<int32_t>(getpid());
    (void)lcm.publish(kGdosListenerChannel, &l);
  }
};

GdosSubscriber::GdosSubscriber(const std::string& url, const std::string& channel, bool announce, std::string name,
                               const std::string& key_file)
    : impl_(std::make_unique<Impl>(url, channel, announce, std::move(name), key_file)) {
  if (!impl_->lcm.good()) throw std::runtime_error(join_error(url));
  // Raw handlers: a batch that does not decode is counted, not thrown.
  impl_->lcm.subscribe(channel, &Impl::on_batch, impl_.get())->setQueueCapacity(4096);
  impl_->lcm.subscribe(kAnnounceChannel, &Impl::on_announce, impl_.get())->setQueueCapacity(256);
}

GdosSubscriber::~GdosSubscriber() = default;

std::size_t GdosSubscriber::poll(int timeout_ms, const std::function<void(const GdosRecord&)>& sink) {
  impl_->sink = &sink;
  impl_->handled = 0;
  const int64_t end = rt::monotonic_ns() + static_cast<int64_t>(timeout_ms) * rt::kNsPerMs;
  pollfd pfd{impl_->lcm.getFileno(), POLLIN, 0};
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
    // poll() on LCM's descriptor, not handleTimeout() (select() aborts above fd 1023).
    const int rc = ::poll(&pfd, 1, static_cast<int>(left_ms));
    if (rc > 0 && (pfd.revents & POLLIN) != 0) {
      impl_->lcm.handle();
      // Drain what else is queued without waiting.
      while (::poll(&pfd, 1, 0) > 0 && (pfd.revents & POLLIN) != 0) {
        pfd.revents = 0;
        impl_->lcm.handle();
      }
    }
    if (impl_->handled > 0 || rt::monotonic_ns() >= end) break;
  }
  impl_->sink = nullptr;
  return impl_->handled;
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
