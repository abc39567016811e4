// LcmTransport: set-up (joining the networks), the transport's four kinds of thread
// (a receiver per network, two senders, maintenance), the refusal of malformed input,
// and the public calls of rack/tims/lcm_transport.h. lcm_transport_impl.h says which
// file holds the rest.
#include "rack/tims/lcm_transport.h"

#include <poll.h>
#include <pthread.h>
#include <sys/random.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <iostream>
#include <stdexcept>

#include "lcm_transport_impl.h"
#include "rack/rt/clock.h"
#include "rack/rt/thread.h"
#include "rack/tims/lcm_url.h"

namespace rack::tims {

const char* describe(NetworkScope s) noexcept { return s == NetworkScope::kRobot ? "robot" : "fleet"; }
const char* describe(Compression c) noexcept { return c == Compression::kZstd ? "zstd" : "none"; }
const char* describe(NodeRole r) noexcept {
  switch (r) {
    case NodeRole::kExecutor: return "executor";
    case NodeRole::kSystemRouter: return "system_router";
    case NodeRole::kTopRouter: return "top_router";
    case NodeRole::kTool: return "tool";
  }
  return "unknown";
}

using namespace lcm_detail;

namespace {

int64_t random_origin() {
  int64_t v = 0;
  while (v == 0) {
    if (getrandom(&v, sizeof v, 0) != static_cast<ssize_t>(sizeof v)) {
      v = rt::monotonic_ns() ^ (static_cast<int64_t>(getpid()) << 32);
    }
  }
  return v;
}

}  // namespace

LcmTransport::Impl::Impl(Router& r, LcmTransportConfig c)
    : router(r),
      config(std::move(c)),
      origin(random_origin()),
      uplink(Address::make(kToolSystem, classes::kTool, 0xFF, 0xFF), config.uplink_slots, config.uplink_slot_size),
      large_uplink(Address::make(kToolSystem, classes::kTool, 0xFF, 0xFE), std::max<uint32_t>(config.large_slots, 1),
                   std::max(config.max_message_bytes, config.uplink_slot_size)),
      control(kTransportControlAddress, 16, 512),
      warn(config.warn ? config.warn : [](const std::string& s) { std::cerr << s << std::endl; }) {
  if (config.networks.empty()) {
    NetworkConfig n;
    n.url = config.url;
    config.networks.push_back(n);
  }
  own_system = router.system();
}

LcmTransport::Impl::~Impl() {
  for (auto& n : networks) {
    if (n->raw_fd >= 0) close(n->raw_fd);
    if (n->cctx != nullptr) ZSTD_freeCCtx(n->cctx);
    if (n->dctx != nullptr) ZSTD_freeDCtx(n->dctx);
  }
}

void LcmTransport::Impl::join() {
  for (std::size_t i = 0; i < config.networks.size(); ++i) {
    auto n = std::make_unique<Network>();
    n->impl = this;
    n->index = i;
    n->config = config.networks[i];
    if (const LcmUrlResult u = parse_lcm_url(n->config.url); !u.ok()) {
      throw std::runtime_error("cannot join the LCM network '" + n->config.name + "': " + u.error);
    }
    n->lcm = std::make_unique<lcm::LCM>(n->config.url);
    if (!n->lcm->good()) {
      throw std::runtime_error("cannot join the LCM network '" + n->config.url +
                               "' (a network namespace needs 'ip link set lo up' and a multicast "
                               "route: ip route add 224.0.0.0/4 dev IFACE)");
    }
    if (!n->config.key_file.empty()) {
      try {
        n->keys = std::make_unique<KeyRing>(n->config.key_file);
      } catch (const std::exception& e) {
        throw std::runtime_error("network '" + n->config.name + "': " + e.what());
      }
      n->signer = std::make_unique<LinkSigner>(*n->keys, origin);
      n->verifier = std::make_unique<LinkVerifier>(*n->keys, config.replay_window_ns);
      n->scratch.reserve(4096);
    }
    n->packet.assign(kPacketPrefix + kChunk + kAuthTrailerBytes, 0);
    put_be(n->packet.data(), static_cast<uint64_t>(rack_lcm::tims_packet::getHash()), 8);
    if (n->config.compression == Compression::kZstd) {
      n->compressed.resize(ZSTD_compressBound(config.max_message_bytes));
      n->cctx = ZSTD_createCCtx();
    }
    n->dctx = ZSTD_createDCtx();
    n->message.resize(config.max_message_bytes);
    n->slots.resize(std::max<uint32_t>(config.reassembly_slots, 1));
    const uint32_t max_chunks = (config.max_message_bytes + kChunk - 1) / kChunk + 1;
    // Compressed streams can exceed the message a little (incompressible data).
    const std::size_t max_encoded = ZSTD_compressBound(config.max_message_bytes);
    for (auto& s : n->slots) {
      s.data.resize(max_encoded);
      s.have.resize(max_chunks + 1);
    }
    if (const auto u = lcm_rx::parse_udpm(n->config.url)) {
      // LCM then only publishes: it opens its receive socket and thread on the first
      // subscription, and there is none.
      n->raw_fd = lcm_rx::open_udpm_socket(n->config.url, *u);
      n->datagram.resize(65536);
    } else {
      auto* sub = n->lcm->subscribe(kTimsChannel, &Network::on_packet, n.get());
      sub->setQueueCapacity(1024);  // LCM's default (~30) silently drops bursts
      n->lcm->subscribe(kAnnounceChannel, &Network::on_announce, n.get())->setQueueCapacity(256);
      n->lcm->subscribe(kDiscoverChannel, &Network::on_discover, n.get())->setQueueCapacity(64);
    }
    networks.push_back(std::move(n));
  }
}

// Every refusal of malformed input: counted in `malformed` and in the counter of its
// kind (LCM framing, announcement, discover request, TiMS packet or message), and
// logged at most once a second per kind with the reason.
void LcmTransport::Impl::reject(Network& n, const std::string& kind, const std::function<std::string()>& why) {
  bump(malformed);
  bump(kind == "lcm"        ? malformed_lcm
       : kind == "announce" ? malformed_announce
       : kind == "discover" ? malformed_discover
                            : malformed_packet);
  warn("malformed " + kind, [&] {
    return "TiMS/LCM: dropped a malformed packet on network '" + n.config.name + "' (" + n.config.url + "): " + why();
  });
}

void LcmTransport::Impl::receive_loop(Network& n) {
  pollfd pfd{n.raw_fd >= 0 ? n.raw_fd : n.lcm->getFileno(), POLLIN, 0};
  while (running.load(std::memory_order_acquire)) {
    pfd.revents = 0;
    const int rc = poll(&pfd, 1, 50);
    if (rc > 0 && (pfd.revents & POLLIN) != 0) {
      guarded(n, [&] {
        if (n.raw_fd < 0) {
          n.lcm->handle();
        } else {
          // Drain what is there; a burst (a large message) is many datagrams.
          for (int i = 0; i < 256; ++i) {
            if (!read_datagram(n)) break;
          }
        }
      });
    }
    expire_reassembly(n);
  }
}

void LcmTransport::Impl::maintenance_loop() {
  int64_t next_announce = rt::monotonic_ns() + config.announce_period_ns;
  int64_t next_key_check = rt::monotonic_ns() + rt::kNsPerSec;
  while (running.load(std::memory_order_acquire)) {
    rt::sleep_for(50 * rt::kNsPerMs);
    if (rt::monotonic_ns() >= next_key_check) {
      reload_keys();
      next_key_check = rt::monotonic_ns() + rt::kNsPerSec;
    }
    if (config.announce_period_ns > 0 && rt::monotonic_ns() >= next_announce) {
      publish_announcement(nullptr);
      next_announce = rt::monotonic_ns() + config.announce_period_ns;
    }
    answer_pending_discovers();
    expire_hosts();
    while (control.peek(Mailbox::kNonBlocking).status == RecvStatus::kOk) control.peek_end();
  }
}

void LcmTransport::Impl::send_loop(Mailbox& box) {
  while (running.load(std::memory_order_acquire)) {
    const auto p = box.peek(100 * rt::kNsPerMs);
    if (p.status == RecvStatus::kClosed) break;
    if (p.status != RecvStatus::kOk) continue;
    const MessageHeader h = *p.header;
    const auto* bytes = reinterpret_cast<const std::byte*>(p.header);
    bool answer_na = false, drop = false;
    {
      std::lock_guard lock(table_mutex);
      track_subscription_locked(h, p.body);
      if (h.type == msg::kData && router.find(h.source()) != nullptr) {
        const uint64_t key = (uint64_t{h.source().component().raw()} << 32) | h.dest;
        if (streams.size() < 4096 || streams.count(key) != 0) streams[key] = rt::monotonic_ns();
      }
      if (h.destination().system() != kToolSystem && !known_locked(h.destination()) &&
          authoritative_locked(h.destination().system())) {
        (h.is_request() ? answer_na : drop) = true;
      }
    }
    if (answer_na || drop) {
      box.peek_end();
      if (answer_na) {
        bump(not_available);
        const MessageHeader reply = make_reply_header(h, msg::kNotAvailable, 0);
        (void)router.send(reply, std::span<const ConstBuffer>{});
      } else {
        bump(not_for_us);
      }
      continue;
    }
    const int32_t seq = next_message_seq();
    // The peeked slot is ours until peek_end(): chunks may go out in place.
    for_networks_to(h.destination(),
                    [&](Network& n) { (void)publish_message(n, bytes, h.length, origin, 0, 0, seq, true); });
    box.peek_end();
    notify_drained();
  }
}

void LcmTransport::Impl::notify_drained() {
  const int64_t threshold = drain_threshold.load(std::memory_order_acquire);
  if (threshold < 0 || uplink_queued() > threshold) return;
  std::lock_guard lock(drain_mutex);
  drained.notify_all();
}

LcmTransport::LcmTransport(Router& router, LcmTransportConfig config)
    : impl_(std::make_unique<Impl>(router, std::move(config))) {
  impl_->join();
}

LcmTransport::~LcmTransport() { stop(); }

void LcmTransport::start() {
  Impl& m = *impl_;
  if (m.running.exchange(true)) return;
  m.started_ns = rt::monotonic_ns();
  m.router.set_uplink(&m.uplink, &m.large_uplink);
  m.router.add(m.control);
  for (auto& n : m.networks) {
    Impl::Network* net = n.get();
    // Named for top/ps on a robot (and bench_lcm's CPU accounting).
    net->receiver = std::thread([&m, net] {
      pthread_setname_np(pthread_self(), "tims-rx");
      if (const int prio = m.config.receive_priority; prio > 0) {
        if (const int err = rt::set_current_thread_priority(prio); err != 0) {
          m.warn("rx priority " + net->config.name, [&] {
            return "TiMS/LCM: the receive thread of network '" + net->config.name +
                   "' cannot run at SCHED_FIFO priority " + std::to_string(prio) + " (" + std::strerror(err) +
                   "): it stays at normal scheduling";
          });
        }
      }
      m.receive_loop(*net);
    });
  }
  m.sender = std::thread([&m] {
    pthread_setname_np(pthread_self(), "tims-tx");
    m.send_loop(m.uplink);
  });
  m.large_sender = std::thread([&m] {
    pthread_setname_np(pthread_self(), "tims-tx-large");
    m.send_loop(m.large_uplink);
  });
  m.maintenance = std::thread([&m] {
    pthread_setname_np(pthread_self(), "tims-maint");
    m.maintenance_loop();
  });
  m.publish_announcement(nullptr);
  request_discovery();
}

void LcmTransport::stop() {
  if (!impl_ || !impl_->running.exchange(false)) return;
  Impl& m = *impl_;
  m.router.set_uplink(nullptr);
  m.uplink.close();
  m.large_uplink.close();
  m.router.remove(m.control.address());
  for (auto& n : m.networks) {
    if (n->receiver.joinable()) n->receiver.join();
  }
  if (m.sender.joinable()) m.sender.join();
  if (m.large_sender.joinable()) m.large_sender.join();
  if (m.maintenance.joinable()) m.maintenance.join();
}

bool LcmTransport::wait_uplink(uint32_t max_queued, int64_t timeout_ns) {
  Impl& m = *impl_;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  std::unique_lock lock(m.drain_mutex);
  // One waiter's threshold at a time is enough for the tools that use this; a second
  // waiter with another threshold still wakes by the timeout's bounded re-checks.
  m.drain_threshold.store(max_queued, std::memory_order_release);
  bool ok = true;
  while (m.uplink_queued() > max_queued) {
    if (!m.running.load()) {  // stopped with messages queued: they will not drain
      ok = false;
      break;
    }
    // The sender reads the threshold after its mailbox changed and notifies under the
    // mutex, so no wake-up is lost; the 10 ms re-check is a bound, not the mechanism.
    if (m.drained.wait_until(lock, std::min(deadline, std::chrono::steady_clock::now() +
                                                          std::chrono::milliseconds(10))) == std::cv_status::timeout &&
        std::chrono::steady_clock::now() >= deadline) {
      ok = m.uplink_queued() <= max_queued;
      break;
    }
  }
  m.drain_threshold.store(-1, std::memory_order_release);
  return ok;
}

void LcmTransport::wait_until_warm() const {
  while (impl_->running.load() && !impl_->warm()) rt::sleep_for(10 * rt::kNsPerMs);
}

TransportCounters LcmTransport::counters() const noexcept {
  const Impl& m = *impl_;
  const auto r = [](const std::atomic<uint64_t>& a) { return a.load(std::memory_order_relaxed); };
  TransportCounters c;
  c.packets_in = r(m.packets_in);
  c.packets_out = r(m.packets_out);
  c.messages_in = r(m.messages_in);
  c.messages_out = r(m.messages_out);
  c.malformed = r(m.malformed);
  c.forged = r(m.forged);
  c.not_for_us = r(m.not_for_us);
  c.forwarded = r(m.forwarded);
  c.not_available = r(m.not_available);
  c.sequence_gaps = r(m.sequence_gaps);
  c.lost_messages = r(m.lost_messages);
  c.publish_errors = r(m.publish_errors);
  c.delivery_failed = r(m.delivery_failed);
  c.hosts_expired = r(m.hosts_expired);
  c.subscriptions_failed = r(m.subscriptions_failed);
  c.streams_stopped = r(m.streams_stopped);
  c.compressed_out = r(m.compressed_out);
  c.bytes_out = r(m.bytes_out);
  c.wire_bytes_out = r(m.wire_bytes_out);
  c.auth_failed = r(m.auth_failed);
  c.replayed = r(m.replayed);
  c.malformed_lcm = r(m.malformed_lcm);
  c.malformed_packet = r(m.malformed_packet);
  c.malformed_announce = r(m.malformed_announce);
  c.malformed_discover = r(m.malformed_discover);
  c.lcm_fragments = r(m.lcm_fragments);
  c.hosts_refused = r(m.hosts_refused);
  c.discovers_answered = r(m.discovers_answered);
  c.discovers_suppressed = r(m.discovers_suppressed);
  return c;
}

void LcmTransport::handle_datagram(const uint8_t* data, std::size_t size, std::size_t network) {
  Impl& m = *impl_;
  if (network >= m.networks.size()) return;
  m.guarded(*m.networks[network], [&] { m.on_datagram(*m.networks[network], data, size); });
}

const std::string& LcmTransport::url() const noexcept { return impl_->config.networks.front().url; }
int64_t LcmTransport::origin() const noexcept { return impl_->origin; }

}  // namespace rack::tims
