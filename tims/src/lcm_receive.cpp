#include "lcm_receive.h"

#include "rack/tims/lcm_url.h"

#include <arpa/inet.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace rack::tims::lcm_rx {

std::optional<UdpmUrl> parse_udpm(const std::string& url) {
  // The one LCM URL parser (rack/tims/lcm_url.h), the same the host-file loader uses.
  const LcmUrlResult r = parse_lcm_url(url);
  if (!r.ok() || r.url.provider != "udpm") return std::nullopt;
  UdpmUrl u;
  u.group.s_addr = htonl(r.url.group);
  u.port = r.url.port;
  u.recv_buf_size = static_cast<int>(r.url.recv_buf_size);
  return u;
}

int open_udpm_socket(const std::string& url, const UdpmUrl& u) {
  int fd = -1;
  const auto fail = [&](const char* what) {
    const std::string why = std::string(what) + ": " + std::strerror(errno);
    if (fd >= 0) close(fd);
    throw std::runtime_error("cannot join the LCM network '" + url + "' (" + why +
                             "; a network namespace needs 'ip link set lo up' and a multicast route: "
                             "ip route add 224.0.0.0/4 dev IFACE)");
  };
  fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) fail("socket");
  const int one = 1;
  if (setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0) fail("SO_REUSEADDR");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_ANY);
  addr.sin_port = htons(u.port);
  if (bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) fail("bind");
  ip_mreq mreq{};
  mreq.imr_multiaddr = u.group;
  mreq.imr_interface.s_addr = htonl(INADDR_ANY);
  if (setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &mreq, sizeof mreq) != 0) fail("IP_ADD_MEMBERSHIP");
  if (u.recv_buf_size > 0) {
    // Capped by net.core.rmem_max, as for LCM (README: socket buffers).
    (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &u.recv_buf_size, sizeof u.recv_buf_size);
  }
  return fd;
}

LcmSocketReader::LcmSocketReader(const std::string& url, const UdpmUrl& u, std::size_t buffer_bytes)
    : fd_(open_udpm_socket(url, u)), buffer_(std::max<std::size_t>(buffer_bytes, 128)) {}

LcmSocketReader::~LcmSocketReader() {
  if (fd_ >= 0) close(fd_);
}

bool LcmSocketReader::read(ReadDatagram& out, const std::function<void(const char*, const std::string&)>& refused,
                           int max_refused) {
  for (int i = 0; i < max_refused; ++i) {
    const ssize_t got = recv(fd_, buffer_.data(), buffer_.size(), MSG_DONTWAIT | MSG_TRUNC);
    if (got < 0) return false;
    ++counters_.datagrams;
    const auto size = static_cast<std::size_t>(got);
    const std::size_t have = std::min(size, buffer_.size());
    const wire_lcm::LcmDatagram g = wire_lcm::parse_datagram(buffer_.data(), have);
    if (g.kind == wire_lcm::LcmDatagram::kFragment) {
      ++counters_.fragments;
      if (refused) {
        refused("fragment", "LCM fragment of " + std::to_string(size) +
                                " bytes refused (RACK-RT never sends messages above 64 KB)");
      }
      continue;
    }
    if (g.kind != wire_lcm::LcmDatagram::kMessage) {
      ++counters_.bad_framing;
      if (refused) refused("framing", std::to_string(size) + "-byte datagram: " + g.why);
      continue;
    }
    out.datagram = g;
    out.size = size;
    out.truncated = size > buffer_.size();
    return true;
  }
  return false;
}

}  // namespace rack::tims::lcm_rx
