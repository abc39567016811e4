#include "rack/sims/nmea_gps_sim.h"

#include <fcntl.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <system_error>

#include "rack/devices/nmea.h"
#include "rack/rt/clock.h"

namespace rack::sims {

namespace {

std::string with_checksum(const std::string& body) {
  char tail[8];
  std::snprintf(tail, sizeof tail, "*%02X\r\n", devices::NmeaParser::checksum(body.data(), body.size()));
  return "$" + body + tail;
}

std::string angle(double v, int deg_digits, char pos, char neg, char* hemi) {
  *hemi = v < 0 ? neg : pos;
  v = std::fabs(v);
  const int deg = static_cast<int>(v);
  const double min = (v - deg) * 60.0;
  char buf[32];
  std::snprintf(buf, sizeof buf, "%0*d%07.4f", deg_digits, deg, min);
  return buf;
}

}  // namespace

NmeaGpsSim::NmeaGpsSim(Config config) : config_(std::move(config)) {}
NmeaGpsSim::~NmeaGpsSim() { stop(); }

std::string NmeaGpsSim::sentences(const Config& c, double lat, double lon, int64_t utc_ns) {
  const int64_t day_ns = 86400LL * rt::kNsPerSec;
  const int64_t tod = utc_ns % day_ns;
  const int64_t days = utc_ns / day_ns;
  // civil from days (Hinnant)
  const int64_t z = days + 719468;
  const int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const int64_t doe = z - era * 146097;
  const int64_t yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const int64_t doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const int64_t mp = (5 * doy + 2) / 153;
  const int64_t d = doy - (153 * mp + 2) / 5 + 1;
  const int64_t m = mp < 10 ? mp + 3 : mp - 9;
  const int64_t y = yoe + era * 400 + (m <= 2 ? 1 : 0);
  char time[16], date[16];
  const double secs = static_cast<double>(tod % (60 * rt::kNsPerSec)) * 1e-9;
  std::snprintf(time, sizeof time, "%02d%02d%05.2f", static_cast<int>(tod / (3600 * rt::kNsPerSec)),
                static_cast<int>(tod / (60 * rt::kNsPerSec) % 60), secs);
  std::snprintf(date, sizeof date, "%02d%02d%02d", static_cast<int>(d), static_cast<int>(m), static_cast<int>(y % 100));
  char ns_h = 'N', ew_h = 'E';
  const std::string la = angle(lat, 2, 'N', 'S', &ns_h);
  const std::string lo = angle(lon, 3, 'E', 'W', &ew_h);
  const std::string t = c.talker;
  char buf[256];
  std::string out;
  std::snprintf(buf, sizeof buf, "%sGGA,%s,%s,%c,%s,%c,1,%02u,%.1f,%.1f,M,47.0,M,,", t.c_str(), time, la.c_str(), ns_h,
                lo.c_str(), ew_h, c.satellites, c.hdop, c.altitude_m);
  out += with_checksum(buf);
  const double knots = c.speed_mps * 3600.0 / 1852.0;
  std::snprintf(buf, sizeof buf, "%sRMC,%s,A,%s,%c,%s,%c,%.2f,%.1f,%s,,,A", t.c_str(), time, la.c_str(), ns_h,
                lo.c_str(), ew_h, knots, c.course_deg, date);
  out += with_checksum(buf);
  std::snprintf(buf, sizeof buf, "%sGSA,A,3,04,05,09,12,17,20,24,25,28,,,,%.1f,%.1f,%.1f", t.c_str(), c.hdop * 1.6,
                c.hdop, c.hdop * 1.3);
  out += with_checksum(buf);
  std::snprintf(buf, sizeof buf, "%sVTG,%.1f,T,,M,%.2f,N,%.2f,K,A", t.c_str(), c.course_deg, knots, c.speed_mps * 3.6);
  out += with_checksum(buf);
  return out;
}

void NmeaGpsSim::open_pty() {
  int master = -1, slave = -1;
  char name[256];
  if (::openpty(&master, &slave, name, nullptr, nullptr) != 0) {
    throw std::system_error(errno, std::generic_category(), "NmeaGpsSim: openpty");
  }
  termios t{};
  ::tcgetattr(slave, &t);
  ::cfmakeraw(&t);  // no echo, no CR/LF translation: bytes as a UART carries them
  ::tcsetattr(slave, TCSANOW, &t);
  ::fcntl(master, F_SETFD, FD_CLOEXEC);
  // Non-blocking: with no reader the pty fills up, and the simulator must never hang on it.
  ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
  ::fcntl(slave, F_SETFD, FD_CLOEXEC);
  std::lock_guard lock(mutex_);
  master_ = master;
  slave_keep_ = slave;
  slave_path_ = name;
  if (!config_.link.empty()) {
    const std::string tmp = config_.link + ".new";
    std::filesystem::remove(tmp);
    std::filesystem::create_symlink(slave_path_, tmp);
    std::filesystem::rename(tmp, config_.link);  // atomic: a driver never sees no link
  }
}

void NmeaGpsSim::close_pty() {
  std::lock_guard lock(mutex_);
  if (master_ >= 0) ::close(master_);
  if (slave_keep_ >= 0) ::close(slave_keep_);
  master_ = slave_keep_ = -1;
}

void NmeaGpsSim::start() {
  open_pty();
  stop_ = false;
  thread_ = std::thread([this] { run(); });
}

void NmeaGpsSim::stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  close_pty();
  if (!config_.link.empty()) {
    std::error_code ec;
    std::filesystem::remove(config_.link, ec);
  }
}

std::string NmeaGpsSim::device() const {
  std::lock_guard lock(mutex_);
  return config_.link.empty() ? slave_path_ : config_.link;
}

void NmeaGpsSim::unplug() { close_pty(); }
void NmeaGpsSim::plug() {
  close_pty();
  open_pty();
}

void NmeaGpsSim::run() {
  const int64_t start = rt::monotonic_ns();
  int64_t next = start;
  const double course = config_.course_deg * M_PI / 180.0;
  constexpr double kEarthRadius = 6371000.0;
  while (!stop_) {
    const double t = static_cast<double>(rt::monotonic_ns() - start) * 1e-9;
    const double north = config_.speed_mps * t * std::cos(course);
    const double east = config_.speed_mps * t * std::sin(course);
    const double lat = config_.latitude_deg + north / kEarthRadius * 180.0 / M_PI;
    const double lon = config_.longitude_deg +
                       east / (kEarthRadius * std::cos(config_.latitude_deg * M_PI / 180.0)) * 180.0 / M_PI;
    std::string out = sentences(config_, lat, lon, rt::host_time_ns());
    const Fault f = fault_.load();
    if (f == Fault::kBadChecksum) {
      for (std::size_t i = out.find('*'); i != std::string::npos; i = out.find('*', i + 1)) {
        out[i + 1] = out[i + 1] == '0' ? '1' : '0';
      }
    } else if (f == Fault::kGarbage) {
      out = std::string("\x01\xff garbage $GPXXX,,,\r\n$GPGGA,1,2*ZZ\r\n\x7f") + out.substr(0, out.size() / 2);
    }
    if (f != Fault::kSilent) {
      std::lock_guard lock(mutex_);
      if (master_ >= 0) {
        (void)!::write(master_, out.data(), out.size());
        epochs_.fetch_add(1);
      }
    }
    next += config_.period_ns;
    rt::sleep_until_monotonic(next);
  }
}

}  // namespace rack::sims
