#include "rack/devices/scip.h"

#include <cstring>

namespace rack::devices::scip {

char checksum(const char* data, std::size_t len) noexcept {
  unsigned sum = 0;
  for (std::size_t i = 0; i < len; ++i) sum += static_cast<uint8_t>(data[i]);
  return static_cast<char>((sum & 0x3F) + 0x30);
}

std::size_t encode3(uint32_t v, char* out) noexcept {
  out[0] = static_cast<char>(((v >> 12) & 0x3F) + 0x30);
  out[1] = static_cast<char>(((v >> 6) & 0x3F) + 0x30);
  out[2] = static_cast<char>((v & 0x3F) + 0x30);
  return 3;
}

uint32_t decode(const char* in, std::size_t chars) noexcept {
  uint32_t v = 0;
  for (std::size_t i = 0; i < chars; ++i) v = (v << 6) | static_cast<uint32_t>((in[i] - 0x30) & 0x3F);
  return v;
}

namespace {

bool parse_uint(const char* s, std::size_t n, uint32_t& out) noexcept {
  if (n == 0 || n > 9) return false;
  uint32_t v = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (s[i] < '0' || s[i] > '9') return false;
    v = v * 10 + static_cast<uint32_t>(s[i] - '0');
  }
  out = v;
  return true;
}

// A status or data line: payload then one checksum character.
bool line_ok(const char* line, std::size_t len) noexcept {
  return len >= 2 && checksum(line, len - 1) == line[len - 1];
}

}  // namespace

std::size_t Parser::feed(std::span<const uint8_t> bytes, Callback on_event, void* user) noexcept {
  std::size_t events = 0;
  for (const uint8_t b : bytes) {
    if (b == '\r') continue;  // some firmwares send CR LF
    if (len_ == kMaxBlock) {
      ++counters_.overflows;
      len_ = 0;
    }
    block_[len_++] = static_cast<char>(b);
    if (b == '\n' && len_ >= 2 && block_[len_ - 2] == '\n') {
      char command[2] = {0, 0}, status[2] = {0, 0};
      const Event e = parse_block(command, status);
      len_ = 0;
      if (e != Event::kNone) {
        ++events;
        if (on_event != nullptr) on_event(user, e, command, status);
      }
    } else if (b == '\n' && len_ == 1) {
      len_ = 0;  // a stray empty line between responses
    }
  }
  return events;
}

Parser::Event Parser::parse_block(char command[2], char status[2]) noexcept {
  // Split into lines (without LF); the block ends with an empty line.
  constexpr std::size_t kMaxLines = 128;  // a 1440-step scan has 70 lines
  const char* lines[kMaxLines];
  std::size_t lens[kMaxLines];
  std::size_t n = 0;
  std::size_t start = 0;
  for (std::size_t i = 0; i + 1 < len_; ++i) {  // the last LF is the empty line's
    if (block_[i] == '\n') {
      if (n == kMaxLines) {
        ++counters_.malformed;
        return Event::kNone;
      }
      lines[n] = block_ + start;
      lens[n] = i - start;
      ++n;
      start = i + 1;
    }
  }
  if (n < 2 || lens[0] < 2 || lens[1] != 3) {
    ++counters_.malformed;
    return Event::kNone;
  }
  if (!line_ok(lines[1], 3)) {
    ++counters_.checksum_errors;
    return Event::kNone;
  }
  ++counters_.responses;
  command[0] = lines[0][0];
  command[1] = lines[0][1];
  status[0] = lines[1][0];
  status[1] = lines[1][1];
  const bool md = command[0] == 'M' && command[1] == 'D';
  const bool gd = command[0] == 'G' && command[1] == 'D';
  if (command[0] == 'P' && command[1] == 'P' && status[0] == '0' && status[1] == '0') {
    Parameters p = params_;
    for (std::size_t i = 2; i < n; ++i) {
      const char* l = lines[i];
      const std::size_t len = lens[i];
      const char* colon = static_cast<const char*>(std::memchr(l, ':', len));
      const char* semi = static_cast<const char*>(std::memchr(l, ';', len));
      if (colon == nullptr || semi == nullptr || semi < colon || static_cast<std::size_t>(semi - l) + 2 != len) {
        ++counters_.malformed;
        return Event::kNone;
      }
      // The sum covers "NAME:VALUE"; firmwares that include the ';' exist too.
      const char sum = l[len - 1];
      const auto upto = static_cast<std::size_t>(semi - l);
      if (checksum(l, upto) != sum && checksum(l, upto + 1) != sum) {
        ++counters_.checksum_errors;
        return Event::kNone;
      }
      const char* v = colon + 1;
      const auto vlen = static_cast<std::size_t>(semi - v);
      const auto key = static_cast<std::size_t>(colon - l);
      auto is = [&](const char* k) { return key == 4 && std::memcmp(l, k, 4) == 0; };
      uint32_t value = 0;
      const bool numeric = parse_uint(v, vlen, value);
      if (is("DMIN") && numeric) p.dmin_mm = value;
      else if (is("DMAX") && numeric) p.dmax_mm = value;
      else if (is("ARES") && numeric) p.ares = value;
      else if (is("AMIN") && numeric) p.amin = value;
      else if (is("AMAX") && numeric) p.amax = value;
      else if (is("AFRT") && numeric) p.afrt = value;
      else if (is("SCAN") && numeric) p.scan_rpm = value;
    }
    params_ = p;
    return Event::kParameters;
  }
  // A scan: MD with status 99 (data follows), or GD with status 00.
  const bool scan_status = (md && status[0] == '9' && status[1] == '9') || (gd && status[0] == '0' && status[1] == '0');
  if (!scan_status || n < 3) return Event::kStatus;  // an acknowledgement (MD 00, BM, QT, errors)
  // Echo: MDssssEEEEccsnn / GDssssEEEEcc
  if (lens[0] < 12) {
    ++counters_.malformed;
    return Event::kNone;
  }
  uint32_t first = 0, last = 0, cluster = 0;
  if (!parse_uint(lines[0] + 2, 4, first) || !parse_uint(lines[0] + 6, 4, last) ||
      !parse_uint(lines[0] + 10, 2, cluster) || last < first) {
    ++counters_.malformed;
    return Event::kNone;
  }
  if (cluster == 0) cluster = 1;
  const uint32_t expected = (last - first) / cluster + 1;
  if (expected > kMaxSteps || lens[2] != 5) {
    ++counters_.malformed;
    return Event::kNone;
  }
  if (!line_ok(lines[2], 5)) {
    ++counters_.checksum_errors;
    return Event::kNone;
  }
  Scan& s = scan_;
  s.timestamp_ms = decode(lines[2], 4);
  // Data: concatenate the lines' payloads (without their checksums) and decode by 3.
  char triple[3];
  std::size_t have = 0;
  uint32_t count = 0;
  for (std::size_t i = 3; i < n; ++i) {
    if (!line_ok(lines[i], lens[i])) {
      ++counters_.checksum_errors;
      return Event::kNone;
    }
    for (std::size_t k = 0; k + 1 < lens[i]; ++k) {
      const char c = lines[i][k];
      if (c < 0x30 || c > 0x6F) {
        ++counters_.malformed;
        return Event::kNone;
      }
      triple[have++] = c;
      if (have == 3) {
        if (count == expected) {
          ++counters_.malformed;
          return Event::kNone;
        }
        s.range_mm[count++] = decode(triple, 3);
        have = 0;
      }
    }
  }
  if (count != expected || have != 0) {
    ++counters_.malformed;
    return Event::kNone;
  }
  s.first_step = first;
  s.last_step = last;
  s.cluster = cluster;
  s.count = count;
  ++counters_.scans;
  return Event::kScan;
}

}  // namespace rack::devices::scip
