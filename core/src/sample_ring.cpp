#include "rack/core/sample_ring.h"

#include <cstring>

namespace rack {

namespace {
uint64_t load(const uint64_t* p) noexcept {
  return std::atomic_ref<uint64_t>(*const_cast<uint64_t*>(p)).load(std::memory_order_relaxed);
}
void store(uint64_t* p, uint64_t v) noexcept { std::atomic_ref<uint64_t>(*p).store(v, std::memory_order_relaxed); }
uint64_t load_acquire(const uint64_t* p) noexcept {
  return std::atomic_ref<uint64_t>(*const_cast<uint64_t*>(p)).load(std::memory_order_acquire);
}
constexpr int kReadAttempts = 8;
}  // namespace

const char* describe(RingLookup r) noexcept {
  switch (r) {
    case RingLookup::kOk: return "ok";
    case RingLookup::kEmpty: return "no data yet";
    case RingLookup::kTooOld: return "requested time is older than the oldest sample";
    case RingLookup::kTooNew: return "requested time is newer than the newest sample";
    case RingLookup::kContended: return "ring overwritten while reading";
  }
  return "unknown";
}

SampleRing::SampleRing(uint32_t capacity, uint32_t payload_size)
    : capacity_(capacity < 2 ? 2 : capacity),
      payload_size_(payload_size),
      slot_words_(kHeaderWords + (payload_size + 7) / 8),
      words_(new uint64_t[std::size_t(capacity_) * slot_words_]()) {}

uint64_t SampleRing::write(int64_t time_ns, const void* payload) noexcept {
  const uint64_t seq = head_.load(std::memory_order_relaxed);
  uint64_t* s = slot(seq);
  store(&s[0], 2 * seq + 1);  // odd: being written
  std::atomic_thread_fence(std::memory_order_release);
  store(&s[1], static_cast<uint64_t>(time_ns));
  store(&s[2], seq);
  const auto* src = static_cast<const unsigned char*>(payload);
  const uint32_t full = payload_size_ / 8;
  for (uint32_t w = 0; w < full; ++w) {
    uint64_t v;
    std::memcpy(&v, src + 8 * w, 8);
    store(&s[kHeaderWords + w], v);
  }
  if (payload_size_ % 8 != 0) {
    uint64_t v = 0;
    std::memcpy(&v, src + 8 * full, payload_size_ % 8);
    store(&s[kHeaderWords + full], v);
  }
  std::atomic_ref<uint64_t>(s[0]).store(2 * seq + 2, std::memory_order_release);  // published
  head_.store(seq + 1, std::memory_order_release);
  return seq;
}

bool SampleRing::read_time(uint64_t sequence, int64_t& time) const noexcept {
  const uint64_t* s = slot(sequence);
  if (load_acquire(&s[0]) != 2 * sequence + 2) return false;
  time = static_cast<int64_t>(load(&s[1]));
  std::atomic_thread_fence(std::memory_order_acquire);
  return load(&s[0]) == 2 * sequence + 2;
}

bool SampleRing::read_sequence(uint64_t sequence, wire::SampleHeader& header, void* payload) const noexcept {
  const uint64_t* s = slot(sequence);
  if (load_acquire(&s[0]) != 2 * sequence + 2) return false;
  header.time_ns = static_cast<int64_t>(load(&s[1]));
  header.sequence = load(&s[2]);
  auto* dst = static_cast<unsigned char*>(payload);
  const uint32_t full = payload_size_ / 8;
  for (uint32_t w = 0; w < full; ++w) {
    const uint64_t v = load(&s[kHeaderWords + w]);
    std::memcpy(dst + 8 * w, &v, 8);
  }
  if (payload_size_ % 8 != 0) {
    const uint64_t v = load(&s[kHeaderWords + full]);
    std::memcpy(dst + 8 * full, &v, payload_size_ % 8);
  }
  std::atomic_thread_fence(std::memory_order_acquire);
  return load(&s[0]) == 2 * sequence + 2;
}

RingLookup SampleRing::read(int64_t time_ns, int64_t max_ahead_ns, wire::SampleHeader& header,
                            void* payload) const noexcept {
  for (int attempt = 0; attempt < kReadAttempts; ++attempt) {
    const uint64_t head = head_.load(std::memory_order_acquire);
    if (head == 0) return RingLookup::kEmpty;
    const uint64_t newest = head - 1;
    // The slot after the newest may be under rewrite: the oldest safe one is head-cap+1.
    const uint64_t oldest = head > capacity_ - 1 ? head - (capacity_ - 1) : 0;
    uint64_t pick = newest;
    if (time_ns != 0) {
      int64_t t_old = 0, t_new = 0;
      if (!read_time(oldest, t_old) || !read_time(newest, t_new)) continue;
      if (time_ns < t_old) return RingLookup::kTooOld;
      if (time_ns > t_new + max_ahead_ns) return RingLookup::kTooNew;
      if (time_ns >= t_new) {
        pick = newest;
      } else {
        // Binary search for the first sample with time >= time_ns (times never decrease).
        uint64_t lo = oldest, hi = newest;
        bool ok = true;
        while (lo < hi) {
          const uint64_t mid = lo + (hi - lo) / 2;
          int64_t t = 0;
          if (!read_time(mid, t)) {
            ok = false;
            break;
          }
          if (t < time_ns) lo = mid + 1;
          else hi = mid;
        }
        if (!ok) continue;
        pick = lo;
        if (lo > oldest) {
          int64_t t_lo = 0, t_prev = 0;
          if (!read_time(lo, t_lo) || !read_time(lo - 1, t_prev)) continue;
          if (time_ns - t_prev <= t_lo - time_ns) pick = lo - 1;  // nearest; earlier wins ties
        }
      }
    }
    if (read_sequence(pick, header, payload)) return RingLookup::kOk;
  }
  return RingLookup::kContended;
}

}  // namespace rack
