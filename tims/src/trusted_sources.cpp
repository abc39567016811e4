#include "rack/tims/trusted_sources.h"

#include <algorithm>

namespace rack::tims {

const char* describe(TrustedSources::Verdict v) noexcept {
  switch (v) {
    case TrustedSources::Verdict::kAccept: return "accepted";
    case TrustedSources::Verdict::kRequest: return "a request sent into a data mailbox";
    case TrustedSources::Verdict::kForged: return "not from a subscribed producer";
    case TrustedSources::Verdict::kLate: return "late (from a producer unsubscribed just before)";
  }
  return "unknown";
}

TrustedSources::Entry* TrustedSources::find(uint32_t component) noexcept {
  for (auto& e : entries_) {
    if (e.source.load(std::memory_order_relaxed) == component) return &e;  // writer: its own stores
  }
  return nullptr;
}

bool TrustedSources::trust(Address producer, int64_t now_ns) noexcept {
  const uint32_t c = producer.component().raw();
  if (Entry* e = find(c)) {
    e->retired_ns.store(0, std::memory_order_release);
    return true;
  }
  Entry* spare = nullptr;
  for (auto& e : entries_) {
    if (e.source.load(std::memory_order_relaxed) == kEmpty) {
      spare = &e;
      break;
    }
  }
  if (spare == nullptr) {  // the entry retired longest ago, once its grace has passed
    for (auto& e : entries_) {
      const int64_t r = e.retired_ns.load(std::memory_order_relaxed);
      if (r == 0 || now_ns - r < kLateGraceNs) continue;
      if (spare == nullptr || r < spare->retired_ns.load(std::memory_order_relaxed)) spare = &e;
    }
  }
  if (spare == nullptr) return false;
  // Unpublish, set the state, publish: a reader that sees the new source sees it trusted.
  spare->source.store(kEmpty, std::memory_order_relaxed);
  spare->retired_ns.store(0, std::memory_order_relaxed);
  spare->source.store(c, std::memory_order_release);
  return true;
}

void TrustedSources::retire(Address producer, int64_t now_ns) noexcept {
  if (Entry* e = find(producer.component().raw())) {
    e->retired_ns.store(now_ns > 0 ? now_ns : 1, std::memory_order_release);
  }
}

void TrustedSources::clear() noexcept {
  for (auto& e : entries_) {
    e.source.store(kEmpty, std::memory_order_release);
    e.retired_ns.store(0, std::memory_order_relaxed);
  }
}

bool TrustedSources::trusts(Address producer) const noexcept {
  const uint32_t c = producer.component().raw();
  for (const auto& e : entries_) {
    if (e.source.load(std::memory_order_acquire) == c) return e.retired_ns.load(std::memory_order_relaxed) == 0;
  }
  return false;
}

TrustedSources::Verdict TrustedSources::check(const MessageHeader& h, int64_t now_ns) noexcept {
  const auto refuse = [&](std::atomic<uint64_t>& counter, Verdict v) {
    counter.fetch_add(1, std::memory_order_relaxed);
    last_source_.store(h.src, std::memory_order_relaxed);
    last_type_.store(h.type, std::memory_order_relaxed);
    return v;
  };
  if (h.is_request()) return refuse(requests_, Verdict::kRequest);
  const uint32_t c = h.source().component().raw();
  if (c == owner_) return Verdict::kAccept;
  for (const auto& e : entries_) {
    if (e.source.load(std::memory_order_acquire) != c) continue;
    const int64_t r = e.retired_ns.load(std::memory_order_relaxed);
    if (r == 0) return Verdict::kAccept;
    if (now_ns - r < kLateGraceNs) {
      late_.fetch_add(1, std::memory_order_relaxed);
      return Verdict::kLate;
    }
    break;
  }
  return refuse(forged_, Verdict::kForged);
}

bool TrustedSources::may_answer(int64_t now_ns) noexcept {
  // GCRA ("virtual scheduling"): tat is when the bucket is full again.
  constexpr int64_t kInterval = 1'000'000'000 / kAnswersPerSecond;
  constexpr int64_t kTolerance = (kAnswersPerSecond - 1) * kInterval;
  int64_t tat = answer_tat_.load(std::memory_order_relaxed);
  for (;;) {
    if (tat - now_ns > kTolerance) return false;
    const int64_t next = std::max(tat, now_ns) + kInterval;
    // relaxed: the bucket guards nothing but itself.
    if (answer_tat_.compare_exchange_weak(tat, next, std::memory_order_relaxed)) return true;
  }
}

TrustedSources::Counters TrustedSources::counters() const noexcept {
  Counters c;
  c.forged = forged_.load(std::memory_order_relaxed);
  c.requests = requests_.load(std::memory_order_relaxed);
  c.late = late_.load(std::memory_order_relaxed);
  c.last_source = last_source_.load(std::memory_order_relaxed);
  c.last_type = last_type_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace rack::tims
