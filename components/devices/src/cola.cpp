#include "rack/devices/cola.h"

#include <bit>
#include <cmath>
#include <cstring>

namespace rack::devices::cola {

namespace {

// Space-separated tokenizer over a fixed span.
struct Tokens {
  const char* p;
  const char* end;
  bool next(const char*& tok, std::size_t& len) noexcept {
    while (p < end && *p == ' ') ++p;
    if (p >= end) return false;
    tok = p;
    while (p < end && *p != ' ') ++p;
    len = static_cast<std::size_t>(p - tok);
    return true;
  }
};

bool hex(const char* s, std::size_t n, uint32_t& out) noexcept {
  if (n == 0 || n > 8) return false;
  uint32_t v = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const char c = s[i];
    uint32_t d;
    if (c >= '0' && c <= '9') d = static_cast<uint32_t>(c - '0');
    else if (c >= 'A' && c <= 'F') d = static_cast<uint32_t>(c - 'A' + 10);
    else if (c >= 'a' && c <= 'f') d = static_cast<uint32_t>(c - 'a' + 10);
    else return false;
    v = (v << 4) | d;
  }
  out = v;
  return true;
}

// A number field: hex (as 32-bit two's complement for signed fields), or +/-decimal.
bool number(const char* s, std::size_t n, int64_t& out) noexcept {
  if (n > 0 && (s[0] == '+' || s[0] == '-')) {
    if (n == 1 || n > 11) return false;
    int64_t v = 0;
    for (std::size_t i = 1; i < n; ++i) {
      if (s[i] < '0' || s[i] > '9') return false;
      v = v * 10 + (s[i] - '0');
    }
    out = s[0] == '-' ? -v : v;
    return true;
  }
  uint32_t u = 0;
  if (!hex(s, n, u)) return false;
  out = u;
  return true;
}

bool equals(const char* tok, std::size_t len, const char* text) noexcept {
  const std::size_t n = std::strlen(text);
  return len == n && std::memcmp(tok, text, n) == 0;
}

}  // namespace

std::size_t Parser::feed(std::span<const uint8_t> bytes, Callback on_telegram, void* user) noexcept {
  std::size_t n = 0;
  for (const uint8_t b : bytes) {
    if (b == kStx) {
      if (in_ && len_ > 0) ++counters_.malformed;  // a telegram cut short by the next one
      in_ = true;
      len_ = 0;
      continue;
    }
    if (!in_) {
      ++counters_.garbage_bytes;
      continue;
    }
    if (b == kEtx) {
      in_ = false;
      ++counters_.telegrams;
      const bool is_scan = parse_scan(buf_, len_);
      ++n;
      if (on_telegram != nullptr) on_telegram(user, buf_, len_, is_scan);
      len_ = 0;
      continue;
    }
    if (len_ == kMaxTelegram) {
      ++counters_.overflows;
      in_ = false;
      len_ = 0;
      continue;
    }
    buf_[len_++] = static_cast<char>(b);
  }
  return n;
}

bool Parser::parse_scan(const char* body, std::size_t len) noexcept {
  Tokens t{body, body + len};
  const char* tok;
  std::size_t tl;
  if (!t.next(tok, tl) || !(equals(tok, tl, "sSN") || equals(tok, tl, "sRA"))) return false;
  if (!t.next(tok, tl) || !equals(tok, tl, "LMDscandata")) return false;
  auto bad = [this] {
    ++counters_.malformed;
    return false;
  };
  int64_t v[18];
  // VersionNumber .. MeasurementFrequency: 16 numbers (device status, inputs and outputs
  // are two fields each), then the number of encoders.
  for (int i = 0; i < 17; ++i) {
    if (!t.next(tok, tl) || !number(tok, tl, v[i])) return bad();
  }
  Scan s;
  s.scan_counter = static_cast<uint32_t>(v[6]);
  s.scan_frequency_centihz = static_cast<uint32_t>(v[14]);
  const int64_t encoders = v[16];
  if (encoders < 0 || encoders > 4) return bad();
  for (int64_t i = 0; i < encoders * 2; ++i) {
    int64_t ignored;
    if (!t.next(tok, tl) || !number(tok, tl, ignored)) return bad();
  }
  int64_t channels = 0;
  if (!t.next(tok, tl) || !number(tok, tl, channels) || channels < 1 || channels > 4) return bad();
  bool have_dist = false;
  for (int64_t c = 0; c < channels; ++c) {
    const char* name;
    std::size_t nl;
    if (!t.next(name, nl)) return bad();
    const bool dist = equals(name, nl, "DIST1");
    const bool rssi = equals(name, nl, "RSSI1");
    uint32_t scale_bits = 0, offset_bits = 0;
    int64_t start = 0, step = 0, count = 0;
    if (!t.next(tok, tl) || !hex(tok, tl, scale_bits)) return bad();
    if (!t.next(tok, tl) || !hex(tok, tl, offset_bits)) return bad();
    if (!t.next(tok, tl) || !number(tok, tl, start)) return bad();
    if (!t.next(tok, tl) || !number(tok, tl, step)) return bad();
    if (!t.next(tok, tl) || !number(tok, tl, count)) return bad();
    if (count < 1 || static_cast<uint64_t>(count) > kMaxPoints || step <= 0) return bad();
    const float scale = std::bit_cast<float>(scale_bits);
    const float offset = std::bit_cast<float>(offset_bits);
    if (!(scale > 0.0F) || scale > 1000.0F) return bad();
    // The offset is a float from the telegram too: NaN or infinity made every range of
    // the scan NaN (found by fuzz_cola).
    if (!std::isfinite(offset)) return bad();
    // Start angle: a signed 32-bit value in 1/10000 deg.
    const auto start_signed = static_cast<int32_t>(static_cast<uint32_t>(start));
    if (have_dist && static_cast<uint32_t>(count) != s.count) return bad();
    if (dist) {
      s.start_angle_deg = start_signed / 10000.0;
      s.step_deg = static_cast<double>(step) / 10000.0;
      s.count = static_cast<uint32_t>(count);
      have_dist = true;
    }
    for (int64_t i = 0; i < count; ++i) {
      int64_t raw;
      if (!t.next(tok, tl) || !number(tok, tl, raw)) return bad();
      const float value = static_cast<float>(raw) * scale + offset;
      if (dist) s.range_m[i] = value * 1e-3F;  // mm
      else if (rssi) s.rssi[i] = value;
    }
    if (rssi) s.has_rssi = true;
  }
  if (!have_dist) return bad();
  scan_ = s;
  ++counters_.scans;
  return true;
}

}  // namespace rack::devices::cola
