#include "rack/tims/lcm_transport.h"

#include <poll.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <iostream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <stdexcept>

#include "rack/rt/clock.h"
#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/host_announce.hpp"
#include "rack_lcm/tims_packet.hpp"

namespace rack::tims {

namespace {

constexpr const char* kTimsChannel = "TIMS";
constexpr const char* kAnnounceChannel = "TIMS_ANNOUNCE";
constexpr const char* kDiscoverChannel = "TIMS_DISCOVER";
// Wire layout of tims_packet: 8-byte fingerprint, int32 size (big-endian), bytes.
constexpr std::size_t kPacketPrefix = 12;

void put_be64(uint8_t* p, uint64_t v) {
  for (int i = 7; i >= 0; --i) { p[i] = static_cast<uint8_t>(v); v >>= 8; }
}
uint64_t get_be64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}

// At most one line per second per kind; the rest are counted and summarised.
class RateLimitedWarn {
 public:
  explicit RateLimitedWarn(std::function<void(const std::string&)> sink) : sink_(std::move(sink)) {}
  void operator()(const std::string& kind, const std::string& text) {
    std::lock_guard lock(mutex_);
    const int64_t now = rt::monotonic_ns();
    auto& s = state_[kind];
    if (now - s.last_ns < rt::kNsPerSec) { ++s.suppressed; return; }
    std::string line = text;
    if (s.suppressed > 0) line += " (" + std::to_string(s.suppressed) + " more suppressed)";
    s.suppressed = 0;
    s.last_ns = now;
    sink_(line);
  }

 private:
  struct State { int64_t last_ns = INT64_MIN / 2; uint64_t suppressed = 0; };
  std::function<void(const std::string&)> sink_;
  std::mutex mutex_;
  std::map<std::string, State> state_;
};

}  // namespace

struct LcmTransport::Impl {
  Impl(Router& r, const LcmTransportConfig& c)
      : router(r),
        config(c),
        lcm(c.url),
        uplink(Address::make(kToolSystem, classes::kTool, 0xFF, 0xFF), c.uplink_slots, c.uplink_slot_size),
        warn(c.warn ? c.warn : [](const std::string& s) { std::cerr << s << std::endl; }),
        receive_buffer(c.uplink_slot_size),
        publish_buffer(kPacketPrefix + c.uplink_slot_size) {}

  Router& router;
  LcmTransportConfig config;
  lcm::LCM lcm;
  Mailbox uplink;
  RateLimitedWarn warn;
  std::vector<std::byte> receive_buffer;
  std::vector<uint8_t> publish_buffer;
  std::thread receiver;
  std::thread sender;
  std::atomic<bool> running{false};

  mutable std::mutex hosts_mutex;
  std::map<std::string, HostInfo> hosts;  // by host name + pid
  std::mutex announce_mutex;
  bool have_announcement = false;
  rack_lcm::host_announce announcement;

  std::atomic<uint64_t> packets_in{0}, packets_out{0}, malformed{0}, not_for_us{0},
      publish_errors{0}, delivery_failed{0};

  void on_packet(const lcm::ReceiveBuffer* rbuf, const std::string& channel);
  void on_announce(const lcm::ReceiveBuffer*, const std::string&, const rack_lcm::host_announce* msg);
  void on_discover(const lcm::ReceiveBuffer*, const std::string&, const rack_lcm::discover_request*) {
    publish_announcement();
  }
  void publish_announcement();
  void receive_loop();
  void send_loop();
  void reject(const std::string& why, const std::string& channel) {
    malformed.fetch_add(1, std::memory_order_relaxed);
    warn("malformed", "TiMS/LCM: dropped a malformed packet on '" + channel + "' (" + config.url +
                          "): " + why);
  }
};

void LcmTransport::Impl::on_packet(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  packets_in.fetch_add(1, std::memory_order_relaxed);
  const auto* data = static_cast<const uint8_t*>(rbuf->data);
  const auto size = static_cast<std::size_t>(rbuf->data_size);
  if (size < kPacketPrefix) return reject("shorter than a tims_packet (" + std::to_string(size) + " bytes)", channel);
  if (get_be64(data) != static_cast<uint64_t>(rack_lcm::tims_packet::getHash())) {
    return reject("not a rack_lcm.tims_packet (fingerprint differs)", channel);
  }
  const uint32_t declared = static_cast<uint32_t>(get_be64(data + 4) & 0xFFFFFFFFu);
  if (declared != size - kPacketPrefix) {
    return reject("size field " + std::to_string(static_cast<int32_t>(declared)) + " but " +
                      std::to_string(size - kPacketPrefix) + " bytes follow",
                  channel);
  }
  const std::span<const std::byte> message(reinterpret_cast<const std::byte*>(data + kPacketPrefix),
                                           size - kPacketPrefix);
  MessageHeader header;
  const MessageError err = decode_header(message, header);
  if (err != MessageError::kOk) {
    if (err == MessageError::kLengthMismatch) {
      // We know who sent it: a request to one of our mailboxes gets an ERROR reply.
      if (header.is_request() && router.find(header.destination()) != nullptr &&
          router.find(header.source()) == nullptr) {
        const MessageHeader reply = make_reply_header(header, msg::kError, 0);
        (void)router.send(reply, std::span<const ConstBuffer>{});
      }
      return reject(std::string(describe(err)) + " from " + header.source().str() + " to " +
                        header.destination().str(),
                    channel);
    }
    return reject(describe(err), channel);
  }
  // Our own packets come back to us over multicast: a source of ours means we sent it.
  if (router.find(header.source()) != nullptr) return;
  if (message.size() > receive_buffer.size()) {
    return reject("message of " + std::to_string(message.size()) + " bytes exceeds " +
                      std::to_string(receive_buffer.size()),
                  channel);
  }
  // Header now in host byte order: write it back in front of the body.
  std::memcpy(receive_buffer.data(), &header, sizeof header);
  std::memcpy(receive_buffer.data() + sizeof header, message.data() + sizeof header,
              message.size() - sizeof header);
  const SendStatus s = router.deliver_local({receive_buffer.data(), message.size()});
  if (s == SendStatus::kNotAvailable) {
    not_for_us.fetch_add(1, std::memory_order_relaxed);
  } else if (!delivered(s)) {
    delivery_failed.fetch_add(1, std::memory_order_relaxed);
    warn("delivery", "TiMS/LCM: message from " + header.source().str() + " to " +
                         header.destination().str() + " not delivered: " + describe(s));
  }
}

void LcmTransport::Impl::on_announce(const lcm::ReceiveBuffer*, const std::string&,
                                     const rack_lcm::host_announce* msg) {
  HostInfo info;
  info.host = msg->host;
  info.system = static_cast<uint8_t>(msg->system);
  info.pid = msg->pid;
  info.executor = Address(static_cast<uint32_t>(msg->executor));
  info.last_seen_ns = rt::monotonic_ns();
  for (const auto& c : msg->components) {
    info.components.push_back({Address(static_cast<uint32_t>(c.address)), c.name, c.impl});
  }
  std::lock_guard lock(hosts_mutex);
  hosts[info.host + "/" + std::to_string(info.pid)] = std::move(info);
}

void LcmTransport::Impl::publish_announcement() {
  std::lock_guard lock(announce_mutex);
  if (!have_announcement) return;
  announcement.time_ns = rt::host_time_ns();
  if (lcm.publish(kAnnounceChannel, &announcement) != 0) {
    publish_errors.fetch_add(1, std::memory_order_relaxed);
  }
}

void LcmTransport::Impl::receive_loop() {
  pollfd pfd{lcm.getFileno(), POLLIN, 0};
  int64_t next_announce = rt::monotonic_ns() + config.announce_period_ns;
  while (running.load(std::memory_order_acquire)) {
    pfd.revents = 0;
    const int rc = poll(&pfd, 1, 50);
    if (rc > 0 && (pfd.revents & POLLIN) != 0) lcm.handle();
    if (config.announce_period_ns > 0 && rt::monotonic_ns() >= next_announce) {
      publish_announcement();
      next_announce = rt::monotonic_ns() + config.announce_period_ns;
    }
  }
}

void LcmTransport::Impl::send_loop() {
  const uint64_t hash = static_cast<uint64_t>(rack_lcm::tims_packet::getHash());
  put_be64(publish_buffer.data(), hash);
  while (running.load(std::memory_order_acquire)) {
    const auto p = uplink.peek(100 * rt::kNsPerMs);
    if (p.status == RecvStatus::kClosed) break;
    if (p.status != RecvStatus::kOk) continue;
    const uint32_t len = p.header->length;
    const uint32_t be = __builtin_bswap32(len);
    std::memcpy(publish_buffer.data() + 8, &be, 4);
    std::memcpy(publish_buffer.data() + kPacketPrefix, p.header, len);
    uplink.peek_end();
    if (lcm.publish(kTimsChannel, publish_buffer.data(), kPacketPrefix + len) != 0) {
      publish_errors.fetch_add(1, std::memory_order_relaxed);
      warn("publish", "TiMS/LCM: publish on " + config.url + " failed");
    } else {
      packets_out.fetch_add(1, std::memory_order_relaxed);
    }
  }
}

LcmTransport::LcmTransport(Router& router, LcmTransportConfig config)
    : router_(router), config_(std::move(config)) {
  impl_ = std::make_unique<Impl>(router_, config_);
  if (!impl_->lcm.good()) {
    throw std::runtime_error("cannot join the LCM network '" + config_.url +
                             "' (a network namespace needs 'ip link set lo up' and a multicast "
                             "route: ip route add 224.0.0.0/4 dev lo)");
  }
  auto* sub = impl_->lcm.subscribe(kTimsChannel, &Impl::on_packet, impl_.get());
  sub->setQueueCapacity(1024);  // LCM's default (~30) silently drops bursts
  impl_->lcm.subscribe(kAnnounceChannel, &Impl::on_announce, impl_.get())->setQueueCapacity(256);
  impl_->lcm.subscribe(kDiscoverChannel, &Impl::on_discover, impl_.get());
}

LcmTransport::~LcmTransport() { stop(); }

void LcmTransport::start() {
  if (impl_->running.exchange(true)) return;
  router_.set_uplink(&impl_->uplink);
  impl_->receiver = std::thread([this] { impl_->receive_loop(); });
  impl_->sender = std::thread([this] { impl_->send_loop(); });
  impl_->publish_announcement();
}

void LcmTransport::stop() {
  if (!impl_ || !impl_->running.exchange(false)) return;
  router_.set_uplink(nullptr);
  impl_->uplink.close();
  if (impl_->receiver.joinable()) impl_->receiver.join();
  if (impl_->sender.joinable()) impl_->sender.join();
}

void LcmTransport::set_announcement(HostInfo info) {
  {
    std::lock_guard lock(impl_->announce_mutex);
    auto& a = impl_->announcement;
    a.host = info.host;
    a.system = info.system;
    a.pid = info.pid;
    a.executor = static_cast<int32_t>(info.executor.raw());
    a.components.clear();
    for (const auto& c : info.components) {
      rack_lcm::component_info ci;
      ci.address = static_cast<int32_t>(c.address.raw());
      ci.name = c.name;
      ci.impl = c.impl;
      a.components.push_back(ci);
    }
    a.count = static_cast<int32_t>(a.components.size());
    impl_->have_announcement = true;
  }
  if (impl_->running.load()) impl_->publish_announcement();
}

void LcmTransport::request_discovery() {
  rack_lcm::discover_request req;
  req.time_ns = rt::host_time_ns();
  req.requester = "pid " + std::to_string(getpid());
  if (impl_->lcm.publish(kDiscoverChannel, &req) != 0) {
    impl_->publish_errors.fetch_add(1, std::memory_order_relaxed);
  }
}

std::vector<HostInfo> LcmTransport::hosts() const {
  std::lock_guard lock(impl_->hosts_mutex);
  std::vector<HostInfo> out;
  for (const auto& [key, info] : impl_->hosts) out.push_back(info);
  return out;
}

TransportCounters LcmTransport::counters() const noexcept {
  TransportCounters c;
  c.packets_in = impl_->packets_in.load(std::memory_order_relaxed);
  c.packets_out = impl_->packets_out.load(std::memory_order_relaxed);
  c.malformed = impl_->malformed.load(std::memory_order_relaxed);
  c.not_for_us = impl_->not_for_us.load(std::memory_order_relaxed);
  c.publish_errors = impl_->publish_errors.load(std::memory_order_relaxed);
  c.delivery_failed = impl_->delivery_failed.load(std::memory_order_relaxed);
  return c;
}

}  // namespace rack::tims
