#include "rack/sims/sick_lms1xx_sim.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <system_error>

#include "rack/rt/clock.h"

namespace rack::sims {

namespace {
std::string hex(uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "%X", v);
  return b;
}
}  // namespace

SickLms1xxSim::SickLms1xxSim(Config config) : config_(config) {}
SickLms1xxSim::~SickLms1xxSim() { stop(); }

void SickLms1xxSim::start() {
  listen_fd_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  const int on = 1;
  ::setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(config_.port);
  if (::bind(listen_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 || ::listen(listen_fd_, 2) != 0) {
    const int e = errno;
    ::close(listen_fd_);
    listen_fd_ = -1;
    throw std::system_error(e, std::generic_category(), "SickLms1xxSim: 127.0.0.1:" + std::to_string(config_.port));
  }
  socklen_t len = sizeof a;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&a), &len);
  port_ = ntohs(a.sin_port);
  stop_ = false;
  thread_ = std::thread([this] { run(); });
}

void SickLms1xxSim::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (client_ >= 0) ::close(client_);
  if (listen_fd_ >= 0) ::close(listen_fd_);
  client_ = listen_fd_ = -1;
}

double SickLms1xxSim::range_m(uint32_t index) const {
  const double deg = (config_.start_angle + static_cast<double>(index) * config_.step) / 10000.0 - 90.0;
  const double a = deg * M_PI / 180.0;
  const double c = std::fabs(std::cos(a)), s = std::fabs(std::sin(a));
  double r = 1e9;
  if (c > 1e-9) r = std::min(r, config_.room_front / c);
  if (s > 1e-9) r = std::min(r, config_.room_side / s);
  return std::round(r * 1000.0) / 1000.0;  // whole millimetres, as the sensor reports
}

std::string SickLms1xxSim::scan_telegram(const char* kind) {
  ++counter_;
  const auto us = static_cast<uint32_t>(rt::monotonic_ns() / 1000);
  std::string t = std::string(kind) + " LMDscandata 1 1 " + hex(0x1234567) + " 0 0 " + hex(counter_) + " " +
                  hex(counter_) + " " + hex(us) + " " + hex(us + 100) + " 0 0 0 0 0 " + hex(config_.frequency_centihz) +
                  " " + hex(1) + " 0 2 DIST1 3F800000 00000000 " + hex(static_cast<uint32_t>(config_.start_angle)) +
                  " " + hex(config_.step) + " " + hex(config_.count);
  for (uint32_t i = 0; i < config_.count; ++i) {
    t.push_back(' ');
    t.append(hex(static_cast<uint32_t>(std::lround(range_m(i) * 1000.0))));
  }
  t += " RSSI1 3F800000 00000000 " + hex(static_cast<uint32_t>(config_.start_angle)) + " " + hex(config_.step) + " " +
       hex(config_.count);
  for (uint32_t i = 0; i < config_.count; ++i) {
    t.push_back(' ');
    t.append(hex(200 + i % 50));
  }
  t += " 0 0 0 0 0 0";  // no 8-bit channels, position, name, comment, time, event
  return t;
}

void SickLms1xxSim::send(const std::string& body) {
  if (client_ < 0 || fault_.load() == Fault::kSilent) return;
  std::string out;
  if (fault_.load() == Fault::kGarbage) out.append("garbage\x03\x01");
  out.push_back('\x02');
  out.append(body);
  out.push_back('\x03');
  if (fault_.load() == Fault::kGarbage) out.append("\xff\xfe");
  if (fault_.load() == Fault::kTruncated) out = out.substr(0, out.size() / 2);
  (void)::send(client_, out.data(), out.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
}

void SickLms1xxSim::handle(const std::string& t) {
  if (t.rfind("sMN SetAccessMode", 0) == 0) return send("sAN SetAccessMode 1");
  if (t == "sRN LMDscandata") return send(scan_telegram("sRA"));
  if (t == "sEN LMDscandata 1") {
    send("sEA LMDscandata 1");
    streaming_ = true;
    return;
  }
  if (t == "sEN LMDscandata 0") {
    streaming_ = false;
    return send("sEA LMDscandata 0");
  }
  send("sFA 2");  // "method unknown"
}

void SickLms1xxSim::receive(const char* data, std::size_t n) {
  input_.append(data, n);
  for (;;) {
    const std::size_t s = input_.find('\x02');
    const std::size_t e = s == std::string::npos ? s : input_.find('\x03', s);
    if (e == std::string::npos) break;
    handle(input_.substr(s + 1, e - s - 1));
    input_.erase(0, e + 1);
  }
  if (input_.size() > 4096) input_.clear();
}

void SickLms1xxSim::run() {
  const auto period = static_cast<int64_t>(1e11 / config_.frequency_centihz);
  int64_t next = rt::monotonic_ns() + period;
  char buf[1024];
  while (!stop_) {
    if (drop_.exchange(false) && client_ >= 0) {
      ::close(client_);
      client_ = -1;
      streaming_ = false;
    }
    pollfd p{client_ >= 0 ? client_ : listen_fd_, POLLIN, 0};
    int64_t left = next - rt::monotonic_ns();
    if (left < 0) left = 0;
    const timespec ts = rt::to_timespec(left);
    (void)::ppoll(&p, 1, &ts, nullptr);
    if (client_ < 0) {
      client_ = ::accept4(listen_fd_, nullptr, nullptr, SOCK_CLOEXEC | SOCK_NONBLOCK);
      input_.clear();
      counter_ = 0;
    } else if ((p.revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
      const ssize_t n = ::recv(client_, buf, sizeof buf, MSG_DONTWAIT);
      if (n > 0) {
        receive(buf, static_cast<std::size_t>(n));
      } else if (n == 0 || (errno != EAGAIN && errno != EINTR)) {
        ::close(client_);
        client_ = -1;
        streaming_ = false;
      }
    }
    if (rt::monotonic_ns() >= next) {
      next += period;
      if (streaming_ && client_ >= 0) {
        send(scan_telegram("sSN"));
        scans_.fetch_add(1);
      }
    }
  }
}

}  // namespace rack::sims
