// LcmTransport: set-up (joining the networks), the transport's four kinds of thread
// (a receiver per network, two senders, maintenance), and the public calls of
// rack/tims/lcm_transport.h. lcm_transport_impl.h says which part holds the rest.
#include "rack/tims/lcm_transport.h"

#include <poll.h>
#include <pthread.h>
#include <sys/random.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <iostream>
#include <stdexcept>

#include "lcm_transport_impl.h"
#include "lcm_transport_packet.h"
#include "rack/rt/clock.h"
#include "rack/rt/thread.h"

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

// No networks listed: one robot network on `url`.
LcmTransportConfig with_networks(LcmTransportConfig c) {
  if (c.networks.empty()) {
    NetworkConfig n;
    n.url = c.url;
    c.networks.push_back(n);
  }
  return c;
}

}  // namespace

LcmTransport::Impl::Impl(Router& r, LcmTransportConfig c)
    : router(r),
      config(with_networks(std::move(c))),
      origin(random_origin()),
      uplink(Address::make(kToolSystem, classes::kTool, 0xFF, 0xFF), config.uplink_slots, config.uplink_slot_size),
      large_uplink(Address::make(kToolSystem, classes::kTool, 0xFF, 0xFE), std::max<uint32_t>(config.large_slots, 1),
                   std::max(config.max_message_bytes, config.uplink_slot_size)),
      control(kTransportControlAddress, 16, 512),
      warn(config.warn ? config.warn : [](const std::string& s) { std::cerr << s << std::endl; }),
      discovery(r, config, origin, config.networks.size(), kTransportControlAddress, stats, warn) {}

void LcmTransport::Impl::join() {
  for (std::size_t i = 0; i < config.networks.size(); ++i) {
    networks.push_back(std::make_unique<Network>(*this, i, config.networks[i]));
  }
}

void LcmTransport::Impl::receive_loop(Network& n) {
  pollfd pfd{n.socket.poll_fd(), POLLIN, 0};
  while (running.load(std::memory_order_acquire)) {
    pfd.revents = 0;
    const int rc = poll(&pfd, 1, 50);
    if (rc > 0 && (pfd.revents & POLLIN) != 0) {
      guarded(n, [&] {
        if (!n.socket.own_socket()) {
          n.socket.handle_lcm();
        } else {
          // Drain what is there; a burst (a large message) is many datagrams.
          for (int i = 0; i < 256; ++i) {
            if (!n.read_datagram()) break;
          }
        }
      });
    }
    n.reassembler.expire(rt::monotonic_ns());
  }
}

void LcmTransport::Impl::maintenance_loop() {
  int64_t next_announce = rt::monotonic_ns() + config.announce_period_ns;
  int64_t next_key_check = rt::monotonic_ns() + rt::kNsPerSec;
  while (running.load(std::memory_order_acquire)) {
    rt::sleep_for(50 * rt::kNsPerMs);
    if (rt::monotonic_ns() >= next_key_check) {
      for (auto& n : networks) n->auth.reload(n->log);
      next_key_check = rt::monotonic_ns() + rt::kNsPerSec;
    }
    if (config.announce_period_ns > 0 && rt::monotonic_ns() >= next_announce) {
      publish_announcement(Discovery::kAll);
      next_announce = rt::monotonic_ns() + config.announce_period_ns;
    }
    // The coalesced discover requests whose interval has passed.
    for (auto& n : networks) {
      if (discovery.answer_due(n->index)) publish_announcement(n->index);
    }
    discovery.expire_hosts();
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
    const Discovery::Outgoing verdict = discovery.outgoing(h, p.body);
    if (verdict.answer_not_available || verdict.drop) {
      box.peek_end();
      if (verdict.answer_not_available) {
        bump(stats.not_available);
        const MessageHeader reply = make_reply_header(h, msg::kNotAvailable, 0);
        (void)router.send(reply, std::span<const ConstBuffer>{});
      } else {
        bump(stats.not_for_us);
      }
      continue;
    }
    const int32_t seq = next_message_seq();
    // The peeked slot is ours until peek_end(): chunks may go out in place.
    for_networks_to(h.destination(),
                    [&](Network& n) { (void)n.publish_message(bytes, h.length, origin, 0, 0, seq, true); });
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

// On one network, or on all (Discovery::kAll).
void LcmTransport::Impl::publish_announcement(std::size_t only) {
  discovery.announce(only, [&](std::size_t i, const rack_lcm::host_announce& a) {
    Network& n = *networks[i];
    std::lock_guard plock(n.publish_mutex);
    if (n.publish_typed_locked(kAnnounceChannel, a) != 0) bump(stats.publish_errors);
  });
}

LcmTransport::LcmTransport(Router& router, LcmTransportConfig config)
    : impl_(std::make_unique<Impl>(router, std::move(config))) {
  impl_->join();
}

LcmTransport::~LcmTransport() { stop(); }

void LcmTransport::start() {
  Impl& m = *impl_;
  if (m.running.exchange(true)) return;
  m.discovery.start(rt::monotonic_ns());
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
  m.publish_announcement(Discovery::kAll);
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

void LcmTransport::set_announcement(HostInfo info) {
  Impl& m = *impl_;
  m.discovery.set_announcement(info);
  if (m.running.load()) m.publish_announcement(Discovery::kAll);
}

void LcmTransport::request_discovery() {
  Impl& m = *impl_;
  rack_lcm::discover_request req;
  req.origin = m.origin;
  req.relay = 0;
  req.hops = 0;
  req.time_ns = rt::host_time_ns();
  req.requester = "pid " + std::to_string(getpid());
  for (auto& n : m.networks) {
    std::lock_guard lock(n->publish_mutex);
    if (n->publish_typed_locked(kDiscoverChannel, req) != 0) bump(m.stats.publish_errors);
  }
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
  while (impl_->running.load() && !impl_->discovery.warm()) rt::sleep_for(10 * rt::kNsPerMs);
}

std::vector<HostInfo> LcmTransport::hosts() const { return impl_->discovery.hosts(); }

TransportCounters LcmTransport::counters() const noexcept { return impl_->stats.snapshot(); }

void LcmTransport::handle_datagram(const uint8_t* data, std::size_t size, std::size_t network) {
  Impl& m = *impl_;
  if (network >= m.networks.size()) return;
  Impl::Network& n = *m.networks[network];
  m.guarded(n, [&] { n.on_datagram(data, size); });
}

const std::string& LcmTransport::url() const noexcept { return impl_->config.networks.front().url; }
int64_t LcmTransport::origin() const noexcept { return impl_->origin; }

}  // namespace rack::tims
