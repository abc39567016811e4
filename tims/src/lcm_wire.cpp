#include "lcm_wire.h"

#include <algorithm>
#include <cstring>
#include <exception>
#include <new>

namespace rack::tims::wire_lcm {

namespace {

// A cursor over an lcm-gen encoding (big-endian, strings as int32 length with the NUL,
// bytes, NUL). The first failure is kept (what and at which byte); every later read
// fails too, so a decoder reads on and checks once.
class Reader {
 public:
  Reader(const uint8_t* d, std::size_t size) : d_(d), size_(size) {}

  bool fingerprint(int64_t hash) {
    uint64_t v = 0;
    if (!raw(8, "fingerprint", &v)) return false;
    if (v != static_cast<uint64_t>(hash)) return fail("fingerprint", "not this type (fingerprint differs)");
    return true;
  }
  bool i8(int8_t& v, const char* field) {
    uint64_t x = 0;
    if (!raw(1, field, &x)) return false;
    v = static_cast<int8_t>(static_cast<uint8_t>(x));
    return true;
  }
  bool i32(int32_t& v, const char* field) {
    uint64_t x = 0;
    if (!raw(4, field, &x)) return false;
    v = static_cast<int32_t>(static_cast<uint32_t>(x));
    return true;
  }
  bool i64(int64_t& v, const char* field) {
    uint64_t x = 0;
    if (!raw(8, field, &x)) return false;
    v = static_cast<int64_t>(x);
    return true;
  }
  // lcm-gen's decoder takes length - 1 bytes for any length it finds, 0 and negative
  // included (std::length_error): here a length is at least 1 (the NUL), fits in what
  // is left, its last byte is the NUL and it holds no other.
  bool str(std::string& v, const char* field) {
    const std::size_t at = pos_;
    int32_t len = 0;
    if (!i32(len, field)) return false;
    if (len < 1) return fail(field, "string length " + std::to_string(len) + " (at least 1: the NUL)", at);
    if (static_cast<std::size_t>(len) > size_ - pos_) {
      return fail(field,
                  "string length " + std::to_string(len) + " but " + std::to_string(size_ - pos_) + " bytes left", at);
    }
    const auto n = static_cast<std::size_t>(len);
    if (d_[pos_ + n - 1] != 0) return fail(field, "string not NUL-terminated", at);
    // LCM strings are C strings: lcm-gen encodes up to the first NUL (strlen), so a
    // string with a NUL inside would not survive a relay (and its length would lie).
    if (std::memchr(d_ + pos_, 0, n - 1) != nullptr) return fail(field, "string with a NUL before its end", at);
    v.assign(reinterpret_cast<const char*>(d_ + pos_), n - 1);
    pos_ += n;
    return true;
  }
  // An array count, checked against the bytes left before anything is allocated.
  bool count(int32_t n, std::size_t min_element, const char* field) {
    if (!ok()) return false;
    if (n < 0 || static_cast<std::size_t>(n) > (size_ - pos_) / min_element) {
      return fail(field, "count " + std::to_string(n) + " but " + std::to_string(size_ - pos_) +
                             " bytes left (at least " + std::to_string(min_element) + " per element)");
    }
    return true;
  }

  [[nodiscard]] bool ok() const { return error_.empty(); }
  [[nodiscard]] std::size_t used() const { return pos_; }
  [[nodiscard]] const std::string& error() const { return error_; }
  bool fail(const char* field, const std::string& what) { return fail(field, what, pos_); }
  bool fail(const char* field, const std::string& what, std::size_t at) {
    if (error_.empty()) error_ = std::string(field) + " at byte " + std::to_string(at) + ": " + what;
    return false;
  }

 private:
  bool raw(std::size_t n, const char* field, uint64_t* v) {
    if (!ok()) return false;
    if (n > size_ - pos_) {
      return fail(field, "truncated (" + std::to_string(size_) + " bytes, needs " + std::to_string(pos_ + n) + ")");
    }
    uint64_t x = 0;
    for (std::size_t i = 0; i < n; ++i) x = (x << 8) | d_[pos_ + i];
    *v = x;
    pos_ += n;
    return true;
  }

  const uint8_t* d_;
  std::size_t size_;
  std::size_t pos_ = 0;
  std::string error_;
};

// Runs `body` (which decodes with a Reader) and turns every way out into an int: the
// bytes used, or -1 with `why`. Allocation failures (bounded by the datagram, so only
// under memory exhaustion) are refusals too, never exceptions past this boundary.
template <typename Body>
int guarded(std::string& why, Body body) noexcept {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    why = "out of memory while decoding";
  } catch (const std::exception& e) {
    why = std::string("decoder failed: ") + e.what();
  } catch (...) {
    why = "decoder failed";
  }
  return -1;
}

int finish(const Reader& r, std::string& why) {
  if (!r.ok()) {
    why = r.error();
    return -1;
  }
  return static_cast<int>(r.used());
}

int32_t get32(const uint8_t* p) {
  return static_cast<int32_t>((uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | p[3]);
}

}  // namespace

int decode(const uint8_t* d, std::size_t size, rack_lcm::host_announce& a, std::string& why) noexcept {
  return guarded(why, [&] {
    Reader r(d, size);
    r.fingerprint(rack_lcm::host_announce::getHash());
    r.i32(a.count, "count");
    r.i64(a.origin, "origin");
    r.i64(a.relay, "relay");
    r.i8(a.hops, "hops");
    r.i8(a.role, "role");
    r.i64(a.time_ns, "time_ns");
    r.i64(a.period_ns, "period_ns");
    r.str(a.host, "host");
    r.i32(a.system, "system");
    r.i32(a.host_id, "host_id");
    r.i32(a.pid, "pid");
    r.i32(a.executor, "executor");
    a.components.clear();
    if (r.count(a.count, kMinComponentInfoBytes, "components")) {
      a.components.resize(static_cast<std::size_t>(a.count));
      for (auto& c : a.components) {
        r.i32(c.address, "components.address");
        r.str(c.name, "components.name");
        r.str(c.impl, "components.impl");
      }
    }
    return finish(r, why);
  });
}

int decode(const uint8_t* d, std::size_t size, rack_lcm::discover_request& q, std::string& why) noexcept {
  return guarded(why, [&] {
    Reader r(d, size);
    r.fingerprint(rack_lcm::discover_request::getHash());
    r.i64(q.origin, "origin");
    r.i64(q.relay, "relay");
    r.i8(q.hops, "hops");
    r.i64(q.time_ns, "time_ns");
    r.str(q.requester, "requester");
    return finish(r, why);
  });
}

int decode(const uint8_t* d, std::size_t size, rack_lcm::gdos_batch& b, std::string& why) noexcept {
  return guarded(why, [&] {
    Reader r(d, size);
    r.fingerprint(rack_lcm::gdos_batch::getHash());
    r.i64(b.time_ns, "time_ns");
    r.str(b.host, "host");
    r.i32(b.pid, "pid");
    r.i32(b.count, "count");
    b.records.clear();
    if (r.count(b.count, kMinGdosRecordBytes, "records")) {
      b.records.resize(static_cast<std::size_t>(b.count));
      for (auto& x : b.records) {
        r.i64(x.time_ns, "records.time_ns");
        r.i64(x.sequence, "records.sequence");
        r.i32(x.source, "records.source");
        r.str(x.name, "records.name");
        r.i8(x.level, "records.level");
        r.i32(x.dropped_before, "records.dropped_before");
        r.str(x.text, "records.text");
      }
    }
    return finish(r, why);
  });
}

int decode(const uint8_t* d, std::size_t size, rack_lcm::gdos_listener& l, std::string& why) noexcept {
  return guarded(why, [&] {
    Reader r(d, size);
    r.fingerprint(rack_lcm::gdos_listener::getHash());
    r.i64(l.time_ns, "time_ns");
    r.str(l.name, "name");
    r.i32(l.pid, "pid");
    return finish(r, why);
  });
}

LcmDatagram parse_datagram(const uint8_t* d, std::size_t size) noexcept {
  LcmDatagram g;
  if (size < 8) {
    g.why = "shorter than LCM's 8-byte header";
    return g;
  }
  const auto magic = static_cast<uint32_t>(get32(d));
  g.sequence = static_cast<uint32_t>(get32(d + 4));
  if (magic == kLcmFragmentMagic) {
    g.kind = LcmDatagram::kFragment;
    return g;
  }
  if (magic != kLcmShortMagic) {
    g.why = "not an LCM datagram (magic differs)";
    return g;
  }
  const auto* name = reinterpret_cast<const char*>(d + 8);
  const std::size_t max_name = std::min<std::size_t>(size - 8, kLcmMaxChannel + 1);
  const std::size_t len = strnlen(name, max_name);
  if (len == max_name) {
    g.why = size - 8 <= kLcmMaxChannel ? "LCM channel name not terminated" : "LCM channel name longer than 63 bytes";
    return g;
  }
  g.kind = LcmDatagram::kMessage;
  g.channel = std::string_view(name, len);
  g.payload = d + 8 + len + 1;
  g.payload_size = size - 8 - len - 1;
  return g;
}

}  // namespace rack::tims::wire_lcm
