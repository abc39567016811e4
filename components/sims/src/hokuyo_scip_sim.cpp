#include "rack/sims/hokuyo_scip_sim.h"

#include <poll.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>

#include "pty_device.h"
#include "rack/devices/scip.h"
#include "rack/rt/clock.h"

namespace rack::sims {

namespace scip = devices::scip;

namespace {
std::string status_line(const char* st) {
  std::string s(st, 2);
  return s + scip::checksum(st, 2) + "\n";
}
std::string param(const std::string& kv) { return kv + ";" + scip::checksum(kv.data(), kv.size()) + "\n"; }
}  // namespace

HokuyoScipSim::HokuyoScipSim(Config config)
    : config_(std::move(config)), pty_(std::make_unique<detail::PtyDevice>(config_.link)) {}
HokuyoScipSim::~HokuyoScipSim() { stop(); }

void HokuyoScipSim::start() {
  {
    std::lock_guard lock(mutex_);
    pty_->open();
  }
  stop_ = false;
  thread_ = std::thread([this] { run(); });
}

void HokuyoScipSim::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  std::lock_guard lock(mutex_);
  pty_->close();
  pty_->remove_link();
}

std::string HokuyoScipSim::device() const {
  std::lock_guard lock(mutex_);
  return pty_->device();
}

void HokuyoScipSim::unplug() {
  std::lock_guard lock(mutex_);
  pty_->close();
  streaming_ = false;
  input_.clear();
}

void HokuyoScipSim::plug() {
  std::lock_guard lock(mutex_);
  pty_->open();
  streaming_ = false;
  input_.clear();
}

uint32_t HokuyoScipSim::range_mm(uint32_t step) const {
  const double a = (static_cast<double>(step) - config_.afrt) * 2.0 * M_PI / config_.ares;
  const double c = std::fabs(std::cos(a)), s = std::fabs(std::sin(a));
  double r = 1e9;
  if (c > 1e-9) r = std::min(r, config_.room_front / c);
  if (s > 1e-9) r = std::min(r, config_.room_side / s);
  const auto mm = static_cast<uint32_t>(std::lround(r * 1000.0));
  return mm > config_.dmax_mm ? 0 : mm;  // 0: no echo (an error code below DMIN)
}

void HokuyoScipSim::write(const std::string& s) {
  // Caller holds mutex_.
  if (pty_->master() < 0 || fault_.load() == Fault::kSilent) return;
  (void)!::write(pty_->master(), s.data(), s.size());
}

void HokuyoScipSim::send_scan(const std::string& echo, const char* status, uint32_t first, uint32_t last,
                              uint32_t cluster) {
  std::string data;
  for (uint32_t step = first; step <= last; step += cluster) {
    uint32_t v = range_mm(step);
    for (uint32_t k = 1; k < cluster && step + k <= last; ++k) {
      const uint32_t w = range_mm(step + k);
      if (w != 0 && (v == 0 || w < v)) v = w;  // a cluster reports its nearest echo
    }
    char e[3];
    scip::encode3(v, e);
    data.append(e, 3);
  }
  const auto ts = static_cast<uint32_t>((rt::monotonic_ns() / rt::kNsPerMs) & 0xFFFFFF);
  char tsc[4];
  tsc[0] = static_cast<char>(((ts >> 18) & 0x3F) + 0x30);
  scip::encode3(ts & 0x3FFFF, tsc + 1);
  std::string out = echo + "\n" + status_line(status) + std::string(tsc, 4) + scip::checksum(tsc, 4) + "\n";
  const bool corrupt = fault_.load() == Fault::kBadChecksum;
  for (std::size_t at = 0; at < data.size(); at += 64) {
    const std::string chunk = data.substr(at, 64);
    char sum = scip::checksum(chunk.data(), chunk.size());
    if (corrupt) sum = sum == '0' ? '1' : '0';
    out += chunk + sum + "\n";
  }
  out += "\n";
  if (fault_.load() == Fault::kGarbage) out = "\x01\xfe garbage\nMD!!\n\n\x7f" + out.substr(0, out.size() / 2);
  write(out);
  scans_.fetch_add(1);
}

void HokuyoScipSim::handle_line(const std::string& line) {
  auto ack = [&](const char* st) { write(line + "\n" + status_line(st) + "\n"); };
  const std::string cmd = line.substr(0, 2);
  if (line == "SCIP2.0") return ack("00");
  if (cmd == "BM") return ack("00");
  if (cmd == "QT") {
    streaming_ = false;
    return ack("00");
  }
  if (cmd == "VV") {
    write(line + "\n" + status_line("00") + param("VEND:Hokuyo Automatic Co.,Ltd.") + param("PROD:rack-devsim URG") +
          param("FIRM:2.0") + param("PROT:SCIP 2.0") + param("SERI:H0000000") + "\n");
    return;
  }
  if (cmd == "PP") {
    const Config& c = config_;
    write(line + "\n" + status_line("00") + param("MODL:URG-04LX(rack-devsim)") +
          param("DMIN:" + std::to_string(c.dmin_mm)) + param("DMAX:" + std::to_string(c.dmax_mm)) +
          param("ARES:" + std::to_string(c.ares)) + param("AMIN:" + std::to_string(c.amin)) +
          param("AMAX:" + std::to_string(c.amax)) + param("AFRT:" + std::to_string(c.afrt)) +
          param("SCAN:" + std::to_string(c.scan_rpm)) + "\n");
    return;
  }
  if ((cmd == "MD" && line.size() == 15) || (cmd == "GD" && line.size() == 12)) {
    const uint32_t first = static_cast<uint32_t>(std::atoi(line.substr(2, 4).c_str()));
    const uint32_t last = static_cast<uint32_t>(std::atoi(line.substr(6, 4).c_str()));
    uint32_t cluster = static_cast<uint32_t>(std::atoi(line.substr(10, 2).c_str()));
    if (cluster == 0) cluster = 1;
    if (first < config_.amin || last > config_.amax || last < first) return ack("10");  // bad range
    if (cmd == "GD") return send_scan(line, "00", first, last, cluster);
    md_first_ = first;
    md_last_ = last;
    md_cluster_ = cluster;
    md_echo_ = line;
    ack("00");
    streaming_ = true;
    return;
  }
  ack("0E");  // unknown command
}

void HokuyoScipSim::receive(const char* data, std::size_t n) {
  std::lock_guard lock(mutex_);
  take(data, n);
}

void HokuyoScipSim::take(const char* data, std::size_t n) {
  input_.append(data, n);
  for (std::size_t nl = input_.find_first_of("\r\n"); nl != std::string::npos; nl = input_.find_first_of("\r\n")) {
    const std::string line = input_.substr(0, nl);
    input_.erase(0, nl + 1);
    if (!line.empty()) handle_line(line);
  }
  if (input_.size() > 1024) input_.clear();  // noise without line ends
}

void HokuyoScipSim::run() {
  const int64_t period = static_cast<int64_t>(60e9 / config_.scan_rpm);
  int64_t next_scan = rt::monotonic_ns() + period;
  char buf[256];
  while (!stop_) {
    int fd;
    {
      std::lock_guard lock(mutex_);
      fd = pty_->master();
    }
    int64_t left = next_scan - rt::monotonic_ns();
    if (left < 0) left = 0;
    if (fd >= 0) {
      pollfd p{fd, POLLIN, 0};
      const timespec ts = rt::to_timespec(left);
      (void)::ppoll(&p, 1, &ts, nullptr);
    } else {
      rt::sleep_for(left);
    }
    std::lock_guard lock(mutex_);
    if (pty_->master() >= 0) {
      const ssize_t n = ::read(pty_->master(), buf, sizeof buf);
      if (n > 0) take(buf, static_cast<std::size_t>(n));
    }
    if (rt::monotonic_ns() >= next_scan) {
      next_scan += period;
      if (streaming_) send_scan(md_echo_, "99", md_first_, md_last_, md_cluster_);
    }
  }
}

}  // namespace rack::sims
