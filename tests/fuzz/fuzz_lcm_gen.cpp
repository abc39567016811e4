// The lcm-gen C++ types (rack_lcm::*, tims/lcm/*.lcm) decoded from bytes as a receiver
// of TIMS_ANNOUNCE, TIMS_DISCOVER and the GDOS channels does, then encoded and decoded
// again.
//
// Input: byte 0 picks the type (bits 0-2) and whether the input carries its 8-byte
// type fingerprint itself (bit 7 set) or the harness puts the right one in front (so
// the fuzzer need not find it first); the rest is the message.
//
// lcm-gen 1.3.1's decoders trust their input, so a receiver must check a message
// before it calls decode() (issue 17):
//   - a string length of zero or less makes std::string::assign throw
//     std::length_error (one such TIMS_ANNOUNCE aborted rackd), and a length of
//     INT32_MIN is worse: `len - 1` overflows (undefined behaviour; in practice
//     INT32_MAX) and assign() reads 2 GiB past the datagram (found by this harness:
//     regressions/lcm_gen/);
//   - an array count or byte count is allocated (vector::resize) before the buffer is
//     checked to hold that many elements: a 2^31 count asks for tens of GB.
// This branch has no safe decode wrapper (README.md, "lcm-gen decoders"): the harness
// checks every string length and count first (safe_to_decode below, which walks the
// message as lcm-gen's decoder does), decodes only what passes, and requires decode()
// not to throw on it. The receivers' own total decoders are fuzzed against lcm-gen's
// by fuzz_lcm_types (the network helper's).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <vector>

#include "fuzz_support.h"
#include "rack_lcm/component_info.hpp"
#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/gdos_batch.hpp"
#include "rack_lcm/gdos_listener.hpp"
#include "rack_lcm/gdos_record.hpp"
#include "rack_lcm/host_announce.hpp"
#include "rack_lcm/tims_packet.hpp"

namespace {

using rack::fuzz::FuzzInput;

// Walks a message (after its fingerprint) field by field as lcm-gen's decoder reads it
// and says whether decode() may be called: false on a string length below 1 or a
// count larger than the bytes left could hold. Running out of bytes is fine (decode()
// returns -1 there before it allocates).
class Walk {
 public:
  Walk(const uint8_t* p, std::size_t size) : p_(p), size_(size) {}
  [[nodiscard]] bool safe() const noexcept { return safe_; }
  [[nodiscard]] bool more() const noexcept { return safe_ && !short_; }
  void skip(std::size_t n) noexcept {
    if (pos_ + n > size_) short_ = true;
    else pos_ += n;
  }
  int32_t i32() noexcept {
    if (pos_ + 4 > size_) {
      short_ = true;
      return 0;
    }
    const auto v = static_cast<int32_t>((uint32_t{p_[pos_]} << 24) | (uint32_t{p_[pos_ + 1]} << 16) |
                                        (uint32_t{p_[pos_ + 2]} << 8) | p_[pos_ + 3]);
    pos_ += 4;
    return v;
  }
  void string() noexcept {
    const int32_t n = i32();
    if (short_) return;
    if (n < 1) safe_ = false;
    else skip(static_cast<std::size_t>(n));
  }
  // A count of elements of at least `element` bytes each.
  void count(int32_t n, std::size_t element) noexcept {
    if (short_) return;
    if (n < 0 || static_cast<std::size_t>(n) > (size_ - pos_) / element) safe_ = false;
  }

 private:
  const uint8_t* p_;
  std::size_t size_;
  std::size_t pos_ = 0;
  bool safe_ = true;
  bool short_ = false;
};

// The smallest encodings of the array elements: component_info is an int32 and two
// strings (length + NUL), gdos_record two int64, int32, string, int8, int32, string.
constexpr std::size_t kMinComponentBytes = 4 + 5 + 5;
constexpr std::size_t kMinRecordBytes = 8 + 8 + 4 + 5 + 1 + 4 + 5;

void walk_component(Walk& w) {
  w.skip(4);
  w.string();
  w.string();
}
void walk_record(Walk& w) {
  w.skip(8 + 8 + 4);
  w.string();
  w.skip(1 + 4);
  w.string();
}

template <typename T>
bool safe_to_decode(const uint8_t* m, std::size_t size) {
  Walk w(m, size);
  if constexpr (std::is_same_v<T, rack_lcm::tims_packet>) {
    w.skip(8 + 8 + 4 * 5 + 1 + 1);
    w.count(w.i32(), 1);
  } else if constexpr (std::is_same_v<T, rack_lcm::component_info>) {
    walk_component(w);
  } else if constexpr (std::is_same_v<T, rack_lcm::host_announce>) {
    const int32_t n = w.i32();
    w.skip(8 + 8 + 1 + 1 + 8 + 8);
    w.string();
    w.skip(4 * 4);
    w.count(n, kMinComponentBytes);
    for (int32_t i = 0; i < n && w.more(); ++i) walk_component(w);
  } else if constexpr (std::is_same_v<T, rack_lcm::discover_request>) {
    w.skip(8 + 8 + 1 + 8);
    w.string();
  } else if constexpr (std::is_same_v<T, rack_lcm::gdos_record>) {
    walk_record(w);
  } else if constexpr (std::is_same_v<T, rack_lcm::gdos_batch>) {
    w.skip(8);
    w.string();
    w.skip(4);
    const int32_t n = w.i32();
    w.count(n, kMinRecordBytes);
    for (int32_t i = 0; i < n && w.more(); ++i) walk_record(w);
  } else {
    static_assert(std::is_same_v<T, rack_lcm::gdos_listener>);
    w.skip(8);
    w.string();
  }
  return w.safe();
}

template <typename T>
void decode(FuzzInput& in, bool with_fingerprint) {
  std::vector<uint8_t> bytes;
  if (!with_fingerprint) {
    const auto hash = static_cast<uint64_t>(T::getHash());
    for (int i = 7; i >= 0; --i) bytes.push_back(static_cast<uint8_t>(hash >> (8 * i)));
  }
  const auto rest = in.rest();
  bytes.insert(bytes.end(), rest.begin(), rest.end());
  if (bytes.size() >= 8 && !safe_to_decode<T>(bytes.data() + 8, bytes.size() - 8)) return;
  T msg;
  const int used = msg.decode(bytes.data(), 0, static_cast<int>(bytes.size()));  // must not throw now
  if (used < 0) return;
  FUZZ_CHECK(static_cast<std::size_t>(used) <= bytes.size());
  // What decoded encodes, and decodes again to the same size.
  const int n = msg.getEncodedSize();
  FUZZ_CHECK(n >= 8);
  std::vector<uint8_t> again(static_cast<std::size_t>(n));
  const int written = msg.encode(again.data(), 0, n);
  FUZZ_CHECK(written >= 8 && written <= n);
  T msg2;
  FUZZ_CHECK(msg2.decode(again.data(), 0, written) == written);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzInput in(data, size);
  const uint8_t selector = in.byte();
  const bool with_fingerprint = (selector & 0x80) != 0;
  switch ((selector & 0x07) % 7) {
    case 0: decode<rack_lcm::tims_packet>(in, with_fingerprint); break;
    case 1: decode<rack_lcm::component_info>(in, with_fingerprint); break;
    case 2: decode<rack_lcm::host_announce>(in, with_fingerprint); break;
    case 3: decode<rack_lcm::discover_request>(in, with_fingerprint); break;
    case 4: decode<rack_lcm::gdos_record>(in, with_fingerprint); break;
    case 5: decode<rack_lcm::gdos_batch>(in, with_fingerprint); break;
    default: decode<rack_lcm::gdos_listener>(in, with_fingerprint); break;
  }
  return 0;
}
