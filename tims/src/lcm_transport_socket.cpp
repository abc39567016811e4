// One network's sockets: LCM for publishing, our own udpm socket (or LCM's
// subscriptions) for receiving (lcm_transport_socket.h).
#include "lcm_transport_socket.h"

#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <stdexcept>

#include "lcm_receive.h"
#include "lcm_transport_packet.h"
#include "rack/tims/lcm_url.h"

namespace rack::tims {

using namespace lcm_detail;

LcmSocket::LcmSocket(const NetworkConfig& config, PayloadHandler& handler) : handler_(handler) {
  if (const LcmUrlResult u = parse_lcm_url(config.url); !u.ok()) {
    throw std::runtime_error("cannot join the LCM network '" + config.name + "': " + u.error);
  }
  lcm_ = std::make_unique<lcm::LCM>(config.url);
  if (!lcm_->good()) {
    throw std::runtime_error("cannot join the LCM network '" + config.url +
                             "' (a network namespace needs 'ip link set lo up' and a multicast "
                             "route: ip route add 224.0.0.0/4 dev IFACE)");
  }
  if (const auto u = lcm_rx::parse_udpm(config.url)) {
    // LCM then only publishes: it opens its receive socket and thread on the first
    // subscription, and there is none.
    fd_ = lcm_rx::open_udpm_socket(config.url, *u);
    datagram_.resize(65536);
  } else {
    auto* sub = lcm_->subscribe(kTimsChannel, &LcmSocket::on_lcm, this);
    sub->setQueueCapacity(1024);  // LCM's default (~30) silently drops bursts
    lcm_->subscribe(kAnnounceChannel, &LcmSocket::on_lcm, this)->setQueueCapacity(256);
    lcm_->subscribe(kDiscoverChannel, &LcmSocket::on_lcm, this)->setQueueCapacity(64);
  }
}

LcmSocket::~LcmSocket() {
  if (fd_ >= 0) close(fd_);
}

void LcmSocket::on_lcm(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  handler_.on_payload(channel, static_cast<const uint8_t*>(rbuf->data), rbuf->data_size);
}

int LcmSocket::publish(const char* channel, const uint8_t* buf, std::size_t len) {
  return lcm_->publish(channel, buf, static_cast<unsigned>(len));
}

int LcmSocket::poll_fd() const { return fd_ >= 0 ? fd_ : lcm_->getFileno(); }

void LcmSocket::handle_lcm() { lcm_->handle(); }

ssize_t LcmSocket::read() {
  const ssize_t got = recv(fd_, datagram_.data(), datagram_.size(), MSG_DONTWAIT | MSG_TRUNC);
  if (got >= 0) last_large_ = static_cast<std::size_t>(got) > kPeekBytes;
  return got;
}

ssize_t LcmSocket::peek() {
  const ssize_t got = recv(fd_, datagram_.data(), kPeekBytes, MSG_DONTWAIT | MSG_PEEK | MSG_TRUNC);
  if (got >= 0) last_large_ = static_cast<std::size_t>(got) > kPeekBytes;
  return got;
}

void LcmSocket::discard() { (void)recv(fd_, nullptr, 0, MSG_DONTWAIT); }

ssize_t LcmSocket::read_split(std::size_t head, std::byte* tail, std::size_t tail_bytes) {
  iovec iov[2] = {{datagram_.data(), head}, {tail, tail_bytes}};
  msghdr mh{};
  mh.msg_iov = iov;
  mh.msg_iovlen = 2;
  return recvmsg(fd_, &mh, MSG_DONTWAIT);
}

}  // namespace rack::tims
