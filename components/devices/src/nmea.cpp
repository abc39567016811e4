#include "rack/devices/nmea.h"

#include <cmath>
#include <cstring>

namespace rack::devices {

namespace {

constexpr int kMaxFields = 24;

struct Fields {
  const char* start[kMaxFields];
  std::size_t len[kMaxFields];
  int count = 0;
};

// Splits "GPGGA,a,b,...": fields are not NUL-terminated (spans into the line).
bool split(const char* s, std::size_t len, Fields& f) noexcept {
  f.count = 0;
  std::size_t begin = 0;
  for (std::size_t i = 0; i <= len; ++i) {
    if (i == len || s[i] == ',') {
      if (f.count == kMaxFields) return false;
      f.start[f.count] = s + begin;
      f.len[f.count] = i - begin;
      ++f.count;
      begin = i + 1;
    }
  }
  return true;
}

// Locale-independent decimal parser: [-]digits[.digits]. false on anything else or empty.
bool parse_double(const char* s, std::size_t len, double& out) noexcept {
  if (len == 0) return false;
  std::size_t i = 0;
  bool neg = false;
  if (s[0] == '-' || s[0] == '+') {
    neg = s[0] == '-';
    i = 1;
  }
  double v = 0.0;
  bool digits = false;
  for (; i < len && s[i] >= '0' && s[i] <= '9'; ++i) {
    v = v * 10.0 + (s[i] - '0');
    digits = true;
  }
  if (i < len && s[i] == '.') {
    double scale = 0.1;
    for (++i; i < len && s[i] >= '0' && s[i] <= '9'; ++i) {
      v += (s[i] - '0') * scale;
      scale *= 0.1;
      digits = true;
    }
  }
  if (i != len || !digits) return false;
  out = neg ? -v : v;
  return true;
}

bool parse_uint(const char* s, std::size_t len, unsigned& out) noexcept {
  if (len == 0 || len > 9) return false;
  unsigned v = 0;
  for (std::size_t i = 0; i < len; ++i) {
    if (s[i] < '0' || s[i] > '9') return false;
    v = v * 10 + static_cast<unsigned>(s[i] - '0');
  }
  out = v;
  return true;
}

// ddmm.mmmm (lat) / dddmm.mmmm (lon) + hemisphere; at most max_deg (90 or 180):
// "9614.038,N" has two valid digits of degrees but is no latitude (found by fuzz_nmea).
bool parse_angle(const char* s, std::size_t len, const char* hemi, std::size_t hlen, int deg_digits, char pos, char neg,
                 double& out) noexcept {
  if (len < static_cast<std::size_t>(deg_digits) + 2 || hlen != 1) return false;
  unsigned deg = 0;
  double minutes = 0.0;
  if (!parse_uint(s, static_cast<std::size_t>(deg_digits), deg)) return false;
  if (!parse_double(s + deg_digits, len - static_cast<std::size_t>(deg_digits), minutes)) return false;
  if (minutes < 0.0 || minutes >= 60.0) return false;
  double v = deg + minutes / 60.0;
  if (v > (deg_digits == 2 ? 90.0 : 180.0)) return false;
  if (hemi[0] == neg) v = -v;
  else if (hemi[0] != pos) return false;
  out = v;
  return true;
}

// hhmmss[.sss] -> ns since midnight.
bool parse_time(const char* s, std::size_t len, int64_t& out) noexcept {
  if (len < 6) return false;
  unsigned h = 0, m = 0;
  double sec = 0.0;
  if (!parse_uint(s, 2, h) || !parse_uint(s + 2, 2, m) || !parse_double(s + 4, len - 4, sec)) return false;
  if (h > 23 || m > 59 || sec < 0.0 || sec >= 61.0) return false;
  out = (static_cast<int64_t>(h) * 3600 + m * 60) * 1'000'000'000LL + std::llround(sec * 1e9);
  return true;
}

// ddmmyy -> ns of UTC midnight (days from civil, Howard Hinnant's algorithm).
bool parse_date(const char* s, std::size_t len, int64_t& out) noexcept {
  unsigned d = 0, mo = 0, y = 0;
  if (len != 6 || !parse_uint(s, 2, d) || !parse_uint(s + 2, 2, mo) || !parse_uint(s + 4, 2, y)) return false;
  if (d < 1 || d > 31 || mo < 1 || mo > 12) return false;
  // Two-digit years: 80..99 -> 19xx, else 20xx (GPS did not exist before 1980).
  int year = static_cast<int>(y) + (y >= 80 ? 1900 : 2000);
  const int mon = static_cast<int>(mo);
  year -= mon <= 2 ? 1 : 0;
  const int era = (year >= 0 ? year : year - 399) / 400;
  const int yoe = year - era * 400;
  const int doy = (153 * (mon + (mon > 2 ? -3 : 9)) + 2) / 5 + static_cast<int>(d) - 1;
  const int doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  const int64_t days = static_cast<int64_t>(era) * 146097 + doe - 719468;
  out = days * 86400LL * 1'000'000'000LL;
  return true;
}

bool field_is(const Fields& f, int i, const char* text) noexcept {
  const std::size_t n = std::strlen(text);
  return i < f.count && f.len[i] == n && std::memcmp(f.start[i], text, n) == 0;
}

}  // namespace

uint8_t NmeaParser::checksum(const char* body, std::size_t len) noexcept {
  uint8_t c = 0;
  for (std::size_t i = 0; i < len; ++i) c ^= static_cast<uint8_t>(body[i]);
  return c;
}

void NmeaParser::reset() noexcept {
  len_ = 0;
  in_sentence_ = false;
  overflowed_ = false;
}

std::size_t NmeaParser::feed(std::span<const uint8_t> bytes, Callback on_sentence, void* user) noexcept {
  std::size_t accepted = 0;
  for (const uint8_t b : bytes) {
    if (b == '$') {
      if (in_sentence_ && len_ > 0) ++counters_.malformed;  // a sentence cut short by the next one
      in_sentence_ = true;
      overflowed_ = false;
      len_ = 0;
      line_[len_++] = '$';
      continue;
    }
    if (!in_sentence_) {
      if (b != '\r' && b != '\n') ++counters_.garbage_bytes;
      continue;
    }
    if (b == '\r' || b == '\n') {
      in_sentence_ = false;
      const Sentence s = parse_sentence(line_, len_);
      if (s != Sentence::kNone) {
        ++accepted;
        if (on_sentence != nullptr) on_sentence(user, s);
      }
      len_ = 0;
      continue;
    }
    if (len_ >= kMaxSentence) {
      if (!overflowed_) ++counters_.overlong;
      overflowed_ = true;
      in_sentence_ = false;
      len_ = 0;
      continue;
    }
    if (b < 0x20 || b > 0x7E) {  // NMEA is printable ASCII: line noise
      ++counters_.malformed;
      in_sentence_ = false;
      len_ = 0;
      continue;
    }
    line_[len_++] = static_cast<char>(b);
  }
  return accepted;
}

NmeaParser::Sentence NmeaParser::parse_sentence(const char* s, std::size_t len) noexcept {
  // "$" body "*" HH
  if (len < 10 || s[0] != '$' || s[len - 3] != '*') {
    ++counters_.malformed;
    return Sentence::kNone;
  }
  auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    return -1;
  };
  const int hi = hex(s[len - 2]), lo = hex(s[len - 1]);
  if (hi < 0 || lo < 0) {
    ++counters_.malformed;
    return Sentence::kNone;
  }
  const char* body = s + 1;
  const std::size_t body_len = len - 4;
  if (checksum(body, body_len) != static_cast<uint8_t>(hi * 16 + lo)) {
    ++counters_.checksum_errors;
    return Sentence::kNone;
  }
  Fields f;
  if (!split(body, body_len, f) || f.len[0] != 5) {
    ++counters_.malformed;
    return Sentence::kNone;
  }
  const char* type = f.start[0] + 2;  // skip the talker (GP, GN, ...)
  auto bad = [this] {
    ++counters_.malformed;
    return Sentence::kNone;
  };
  NmeaFix n = fix_;  // commit only a fully parsed sentence
  if (std::memcmp(type, "GGA", 3) == 0) {
    // GGA,time,lat,N,lon,E,quality,sats,hdop,alt,M,geoid,M,age,station
    if (f.count < 15) return bad();
    unsigned q = 0, sats = 0;
    if (!parse_uint(f.start[6], f.len[6], q) || q > 9) return bad();
    n.quality = static_cast<uint8_t>(q);
    if (f.len[1] > 0 && !parse_time(f.start[1], f.len[1], n.time_of_day_ns)) return bad();
    if (f.len[7] > 0 && (!parse_uint(f.start[7], f.len[7], sats) || sats > 255)) return bad();
    n.satellites = static_cast<uint8_t>(sats);
    if (q != 0) {  // a receiver without a fix leaves position fields empty
      if (!parse_angle(f.start[2], f.len[2], f.start[3], f.len[3], 2, 'N', 'S', n.latitude_deg) ||
          !parse_angle(f.start[4], f.len[4], f.start[5], f.len[5], 3, 'E', 'W', n.longitude_deg) ||
          !parse_double(f.start[8], f.len[8], n.hdop) || !parse_double(f.start[9], f.len[9], n.altitude_m)) {
        return bad();
      }
      if (f.len[11] > 0 && !parse_double(f.start[11], f.len[11], n.geoid_separation_m)) return bad();
    }
    if (date_ns_ != 0) n.utc_ns = date_ns_ + n.time_of_day_ns;
    fix_ = n;
    ++counters_.sentences;
    return Sentence::kGga;
  }
  if (std::memcmp(type, "RMC", 3) == 0) {
    // RMC,time,status,lat,N,lon,E,speed_kn,course,date,magvar,E[,mode[,navstatus]]
    if (f.count < 12) return bad();
    if (f.len[2] != 1 || (f.start[2][0] != 'A' && f.start[2][0] != 'V')) return bad();
    n.rmc_valid = f.start[2][0] == 'A';
    if (f.len[1] > 0 && !parse_time(f.start[1], f.len[1], n.time_of_day_ns)) return bad();
    int64_t date = 0;
    if (f.len[9] > 0 && !parse_date(f.start[9], f.len[9], date)) return bad();
    if (n.rmc_valid) {
      double knots = 0.0;
      if (!parse_angle(f.start[3], f.len[3], f.start[4], f.len[4], 2, 'N', 'S', n.latitude_deg) ||
          !parse_angle(f.start[5], f.len[5], f.start[6], f.len[6], 3, 'E', 'W', n.longitude_deg) ||
          !parse_double(f.start[7], f.len[7], knots)) {
        return bad();
      }
      n.speed_mps = knots * (1852.0 / 3600.0);
      if (f.len[8] > 0 && !parse_double(f.start[8], f.len[8], n.course_deg)) return bad();
    }
    if (date != 0) {
      date_ns_ = date;
      n.utc_ns = date_ns_ + n.time_of_day_ns;
    }
    fix_ = n;
    ++counters_.sentences;
    return Sentence::kRmc;
  }
  if (std::memcmp(type, "GSA", 3) == 0) {
    // GSA,sel,mode,12 x prn,pdop,hdop,vdop[,system id]
    if (f.count < 18) return bad();
    unsigned mode = 0;
    if (!parse_uint(f.start[2], f.len[2], mode) || mode < 1 || mode > 3) return bad();
    n.mode = static_cast<uint8_t>(mode);
    if (mode > 1 && (!parse_double(f.start[15], f.len[15], n.pdop) || !parse_double(f.start[16], f.len[16], n.hdop) ||
                     !parse_double(f.start[17], f.len[17], n.vdop))) {
      return bad();
    }
    fix_ = n;
    ++counters_.sentences;
    return Sentence::kGsa;
  }
  if (std::memcmp(type, "VTG", 3) == 0) {
    // VTG,course,T,course_mag,M,speed_kn,N,speed_kmh,K[,mode]
    if (f.count < 9 || !field_is(f, 2, "T") || !field_is(f, 8, "K")) return bad();
    if (f.len[1] > 0 && !parse_double(f.start[1], f.len[1], n.course_deg)) return bad();
    double kmh = 0.0;
    if (f.len[7] > 0) {
      if (!parse_double(f.start[7], f.len[7], kmh)) return bad();
      n.speed_mps = kmh / 3.6;
    }
    fix_ = n;
    ++counters_.sentences;
    return Sentence::kVtg;
  }
  ++counters_.unknown;
  return Sentence::kNone;
}

}  // namespace rack::devices
