#include "rack/tims/access.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include "rack/rt/clock.h"

namespace rack::tims {

const char* describe(AccessVerdict v) noexcept {
  switch (v) {
    case AccessVerdict::kAllowed: return "allowed";
    case AccessVerdict::kDeniedType: return "message type not allowed";
    case AccessVerdict::kDeniedPriority: return "priority above the rule's max_priority";
    case AccessVerdict::kDeniedRate: return "rate limit (messages per second) exceeded";
    case AccessVerdict::kDeniedBandwidth: return "bandwidth limit (bytes per second) exceeded";
    case AccessVerdict::kDeniedDefault: return "no rule allows it and the default policy is closed";
  }
  return "unknown";
}

namespace {

constexpr int64_t kSecond = 1'000'000'000;
constexpr std::size_t type_index(int8_t t) noexcept { return static_cast<std::size_t>(static_cast<int>(t) + 128); }

// Appends `src` to the NUL-terminated `out` of `size` bytes, cut at the end. RT-safe.
void append(char* out, std::size_t size, const char* src) noexcept {
  std::size_t n = strnlen(out, size);
  for (std::size_t i = 0; src[i] != '\0' && n + 1 < size; ++i) out[n++] = src[i];
  if (n < size) out[n] = '\0';
}

uint64_t mix(uint64_t x) noexcept {  // splitmix64's finaliser: spreads keys over the table
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

// GCRA step on one bucket: let `cost` ns of credit through when the bucket stays within
// `tolerance` ns of now. Lock-free (CAS on one atomic).
bool take(std::atomic<int64_t>& tat, int64_t cost, int64_t tolerance, int64_t now) noexcept {
  int64_t old = tat.load(std::memory_order_relaxed);
  for (;;) {
    const int64_t next = std::max(old, now) + cost;
    if (next - now > tolerance) return false;
    // relaxed: the bucket is the only shared state; nothing else is published with it.
    if (tat.compare_exchange_weak(old, next, std::memory_order_relaxed)) return true;
  }
}

std::string type_text(int8_t t) {
  const char* n = msg::name(t);
  return std::to_string(t) + (n != nullptr ? std::string(" (") + n + ")" : std::string());
}

}  // namespace

AccessControl::AccessControl(const AccessConfig& config) : default_(config.default_policy) {
  if (config.rules.size() > kMaxRules) {
    throw std::invalid_argument("access: " + std::to_string(config.rules.size()) + " rules, at most " +
                                std::to_string(kMaxRules));
  }
  for (std::size_t i = 0; i < config.rules.size(); ++i) {
    const AccessRuleConfig& c = config.rules[i];
    Rule& r = rules_[i];
    const std::string name = c.name.empty() ? "rule " + std::to_string(i + 1) : c.name;
    if (c.to.empty()) throw std::invalid_argument("access: rule '" + name + "' has no destination ('to')");
    if (c.to.size() > kMaxMasks || c.from.size() > kMaxMasks) {
      throw std::invalid_argument("access: rule '" + name + "' lists more than " + std::to_string(kMaxMasks) +
                                  " addresses in 'to' or 'from'");
    }
    std::snprintf(r.name.data(), r.name.size(), "%s", name.c_str());
    std::copy(c.to.begin(), c.to.end(), r.to.begin());
    r.to_count = c.to.size();
    std::copy(c.from.begin(), c.from.end(), r.from.begin());
    r.from_count = c.from.size();
    r.from_local = c.from_local;
    r.from_network = c.from_network;
    r.only_local = c.only_local;
    r.any_source = c.from.empty() && !c.from_local && !c.from_network;
    r.any_type = c.any_type;
    r.types = c.types;
    r.restricts_replies = c.restricts_replies;
    r.max_priority = c.max_priority;
    if (c.rate > 0) {
      r.msg_interval_ns = std::max<int64_t>(1, std::llround(1e9 / c.rate));
      const double burst = c.burst > 0 ? c.burst : std::max(1.0, c.rate / 10.0);
      r.msg_tolerance_ns = std::llround(burst * static_cast<double>(r.msg_interval_ns));
    }
    if (c.bandwidth > 0) {
      r.byte_ns = 1e9 / c.bandwidth;
      const double burst = c.burst_bytes > 0 ? c.burst_bytes : std::max(65536.0, c.bandwidth / 10.0);
      r.byte_tolerance_ns = std::llround(burst * r.byte_ns);
    }
  }
  rule_count_ = config.rules.size();
  std::size_t n = 16;
  while (n < config.sources) n <<= 1;
  sources_ = std::make_unique<SourceEntry[]>(n);
  source_mask_ = n - 1;
}

bool AccessControl::matches(const Rule& r, const MessageHeader& h, MessageOrigin origin) const noexcept {
  const Address dest = h.destination();
  bool to = false;
  for (std::size_t i = 0; i < r.to_count && !to; ++i) to = r.to[i].matches(dest);
  if (!to) return false;
  if (r.only_local && origin != MessageOrigin::kLocal) return false;
  if (r.any_source) return true;
  if (r.from_local && origin == MessageOrigin::kLocal) return true;
  if (r.from_network && origin == MessageOrigin::kNetwork) return true;
  const Address src = h.source();
  for (std::size_t i = 0; i < r.from_count; ++i) {
    if (r.from[i].matches(src)) return true;
  }
  return false;
}

AccessVerdict AccessControl::limit(std::size_t rule_index, Rule& r, const MessageHeader& h, int64_t now) noexcept {
  if (r.msg_interval_ns == 0 && r.byte_ns == 0) return AccessVerdict::kAllowed;
  const uint64_t key = (uint64_t{rule_index + 1} << 32) | h.src;
  const std::size_t start = static_cast<std::size_t>(mix(key));
  std::atomic<int64_t>* msg_tat = nullptr;
  std::atomic<int64_t>* byte_tat = nullptr;
  SourceEntry* reusable = nullptr;
  uint64_t reusable_key = 0;
  for (std::size_t p = 0; p < kProbe && msg_tat == nullptr; ++p) {
    SourceEntry& e = sources_[(start + p) & source_mask_];
    uint64_t k = e.key.load(std::memory_order_acquire);
    if (k == 0) {
      // Claim the empty entry (acq_rel: a concurrent claimer of the same key sees ours).
      if (e.key.compare_exchange_strong(k, key, std::memory_order_acq_rel) || k == key) {
        msg_tat = &e.msg_tat;
        byte_tat = &e.byte_tat;
      }
      continue;
    }
    if (k == key) {
      msg_tat = &e.msg_tat;
      byte_tat = &e.byte_tat;
    } else if (reusable == nullptr && e.msg_tat.load(std::memory_order_relaxed) <= now &&
               e.byte_tat.load(std::memory_order_relaxed) <= now) {
      // Full again: forgetting it changes nothing for its old source.
      reusable = &e;
      reusable_key = k;
    }
  }
  if (msg_tat == nullptr && reusable != nullptr &&
      reusable->key.compare_exchange_strong(reusable_key, key, std::memory_order_acq_rel)) {
    msg_tat = &reusable->msg_tat;
    byte_tat = &reusable->byte_tat;
  }
  if (msg_tat == nullptr) {
    overflow_uses_.fetch_add(1, std::memory_order_relaxed);
    msg_tat = &r.overflow_msg_tat;
    byte_tat = &r.overflow_byte_tat;
  }
  if (r.msg_interval_ns != 0 && !take(*msg_tat, r.msg_interval_ns, r.msg_tolerance_ns, now)) {
    return AccessVerdict::kDeniedRate;
  }
  if (r.byte_ns != 0) {
    const auto cost = static_cast<int64_t>(static_cast<double>(h.length) * r.byte_ns);
    if (!take(*byte_tat, cost, r.byte_tolerance_ns, now)) {
      // Give the message credit back: it was not let through.
      if (r.msg_interval_ns != 0) msg_tat->fetch_sub(r.msg_interval_ns, std::memory_order_relaxed);
      return AccessVerdict::kDeniedBandwidth;
    }
  }
  return AccessVerdict::kAllowed;
}

void AccessControl::remember(Rule& r, const MessageHeader& h, AccessVerdict v) noexcept {
  r.last_src_dst.store((uint64_t{h.src} << 32) | h.dest, std::memory_order_relaxed);
  r.last_type_prio_verdict.store((uint32_t{static_cast<uint8_t>(h.type)} << 16) | (uint32_t{h.priority} << 8) |
                                     static_cast<uint32_t>(v),
                                 std::memory_order_relaxed);
}

AccessDecision AccessControl::check(const MessageHeader& h, MessageOrigin origin) noexcept {
  return check(h, origin, rt::monotonic_ns());
}

AccessDecision AccessControl::check(const MessageHeader& h, MessageOrigin origin, int64_t now_ns) noexcept {
  for (std::size_t i = 0; i < rule_count_; ++i) {
    Rule& r = rules_[i];
    if (!matches(r, h, origin)) continue;
    AccessVerdict v = AccessVerdict::kAllowed;
    if (!r.any_type && (h.is_request() || r.restricts_replies) && !r.types.test(type_index(h.type))) {
      v = AccessVerdict::kDeniedType;
    } else if (h.priority > r.max_priority) {
      v = AccessVerdict::kDeniedPriority;
    } else {
      v = limit(i, r, h, now_ns);
    }
    switch (v) {
      case AccessVerdict::kAllowed: r.allowed.fetch_add(1, std::memory_order_relaxed); break;
      case AccessVerdict::kDeniedType: r.denied_type.fetch_add(1, std::memory_order_relaxed); break;
      case AccessVerdict::kDeniedPriority: r.denied_priority.fetch_add(1, std::memory_order_relaxed); break;
      case AccessVerdict::kDeniedRate: r.denied_rate.fetch_add(1, std::memory_order_relaxed); break;
      case AccessVerdict::kDeniedBandwidth: r.denied_bandwidth.fetch_add(1, std::memory_order_relaxed); break;
      case AccessVerdict::kDeniedDefault: break;
    }
    AccessDecision d{v, static_cast<int>(i), false};
    if (v != AccessVerdict::kAllowed) {
      remember(r, h, v);
      d.answer = h.is_request() && take(r.reply_tat, kSecond / kRepliesPerSecond, kSecond, now_ns);
    }
    return d;
  }
  if (default_ == AccessDefault::kClosed && h.is_request()) {
    denied_default_.fetch_add(1, std::memory_order_relaxed);
    default_last_src_dst_.store((uint64_t{h.src} << 32) | h.dest, std::memory_order_relaxed);
    default_last_type_.store((uint32_t{static_cast<uint8_t>(h.type)} << 16) | (uint32_t{h.priority} << 8),
                             std::memory_order_relaxed);
    return AccessDecision{AccessVerdict::kDeniedDefault, -1,
                          take(default_reply_tat_, kSecond / kRepliesPerSecond, kSecond, now_ns)};
  }
  return AccessDecision{AccessVerdict::kAllowed, -1};
}

void AccessControl::denial_text(const AccessDecision& d, char* out, std::size_t size) const noexcept {
  if (size == 0) return;
  out[0] = '\0';
  append(out, size, "access denied");
  if (d.rule >= 0 && static_cast<std::size_t>(d.rule) < rule_count_) {
    append(out, size, " by rule '");
    append(out, size, rules_[static_cast<std::size_t>(d.rule)].name.data());
    append(out, size, "'");
  }
  append(out, size, ": ");
  append(out, size, describe(d.verdict));
}

uint64_t AccessControl::denied_total() const noexcept {
  uint64_t n = denied_default_.load(std::memory_order_relaxed);
  for (std::size_t i = 0; i < rule_count_; ++i) {
    const Rule& r = rules_[i];
    n += r.denied_type.load(std::memory_order_relaxed) + r.denied_priority.load(std::memory_order_relaxed) +
         r.denied_rate.load(std::memory_order_relaxed) + r.denied_bandwidth.load(std::memory_order_relaxed);
  }
  return n;
}

std::vector<AccessRuleCounters> AccessControl::counters() const {
  std::vector<AccessRuleCounters> out;
  for (std::size_t i = 0; i < rule_count_; ++i) {
    const Rule& r = rules_[i];
    AccessRuleCounters c;
    c.name = r.name.data();
    c.allowed = r.allowed.load(std::memory_order_relaxed);
    c.denied_type = r.denied_type.load(std::memory_order_relaxed);
    c.denied_priority = r.denied_priority.load(std::memory_order_relaxed);
    c.denied_rate = r.denied_rate.load(std::memory_order_relaxed);
    c.denied_bandwidth = r.denied_bandwidth.load(std::memory_order_relaxed);
    out.push_back(c);
  }
  return out;
}

std::vector<std::string> AccessControl::report() {
  std::vector<std::string> lines;
  const auto last_text = [](uint64_t src_dst, uint32_t tpv) {
    const MessageHeader h = make_header(Address(static_cast<uint32_t>(src_dst)),
                                        Address(static_cast<uint32_t>(src_dst >> 32)),
                                        static_cast<int8_t>(static_cast<uint8_t>(tpv >> 16)),
                                        static_cast<uint8_t>(tpv >> 8), 0, 0);
    return h.source().str() + " -> " + h.destination().str() + " type " + type_text(h.type) + " priority " +
           std::to_string(h.priority);
  };
  const auto u = [](uint64_t v) { return std::to_string(v); };
  for (std::size_t i = 0; i < rule_count_; ++i) {
    Rule& r = rules_[i];
    const uint64_t dt = r.denied_type.load(std::memory_order_relaxed);
    const uint64_t dp = r.denied_priority.load(std::memory_order_relaxed);
    const uint64_t dr = r.denied_rate.load(std::memory_order_relaxed);
    const uint64_t db = r.denied_bandwidth.load(std::memory_order_relaxed);
    const uint64_t total = dt + dp + dr + db;
    if (total <= r.reported) continue;
    const uint32_t tpv = r.last_type_prio_verdict.load(std::memory_order_relaxed);
    lines.push_back("access: rule '" + std::string(r.name.data()) + "' refused " + u(total - r.reported) +
                    " message(s) since the last report (in all: type " + u(dt) + ", priority " + u(dp) + ", rate " +
                    u(dr) + ", bandwidth " + u(db) +
                    "); last: " + last_text(r.last_src_dst.load(std::memory_order_relaxed), tpv) + ": " +
                    describe(static_cast<AccessVerdict>(tpv & 0xFF)));
    r.reported = total;
  }
  const uint64_t d = denied_default_.load(std::memory_order_relaxed);
  if (d > default_reported_) {
    lines.push_back("access: the closed default policy refused " + u(d - default_reported_) +
                    " request(s) since the last report (in all " + u(d) + "); last: " +
                    last_text(default_last_src_dst_.load(std::memory_order_relaxed),
                              default_last_type_.load(std::memory_order_relaxed)) +
                    ": no rule matches it");
    default_reported_ = d;
  }
  return lines;
}

std::string AccessControl::status_text() const {
  std::string out;
  char line[256];
  const auto u = [](uint64_t v) { return static_cast<unsigned long long>(v); };
  for (const auto& c : counters()) {
    std::snprintf(
        line, sizeof line,
        "  access rule %-18s allowed %llu, denied %llu (type %llu, priority %llu, rate %llu, bandwidth %llu)\n",
        ("'" + c.name + "'").c_str(), u(c.allowed), u(c.denied()), u(c.denied_type), u(c.denied_priority),
        u(c.denied_rate), u(c.denied_bandwidth));
    out += line;
  }
  std::snprintf(line, sizeof line, "  access default %s: denied %llu; source table overflow %llu\n",
                default_ == AccessDefault::kClosed ? "closed" : "open", u(denied_default()), u(overflow_uses()));
  out += line;
  return out;
}

bool parse_message_type(const std::string& text, int8_t& out) noexcept {
  struct Named {
    const char* name;
    int8_t type;
  };
  static constexpr Named kNames[] = {
      {"on", msg::kOn},
      {"off", msg::kOff},
      {"get_status", msg::kGetStatus},
      {"get_data", msg::kGetData},
      {"get_cont_data", msg::kGetContData},
      {"stop_cont_data", msg::kStopContData},
      {"get_next_data", msg::kGetNextData},
      {"get_param", msg::kGetParam},
      {"set_param", msg::kSetParam},
      {"get_stats", msg::kGetStats},
      {"get_latency", msg::kGetLatency},
      {"latency", msg::kLatency},
      {"get_class", msg::kGetClass},
      {"class", msg::kClass},
      {"get_listeners", msg::kGetListeners},
      {"listeners", msg::kListeners},
      {"get_tasks", msg::kGetTasks},
      {"tasks", msg::kTasks},
      {"ok", msg::kOk},
      {"error", msg::kError},
      {"timeout", msg::kTimeout},
      {"not_available", msg::kNotAvailable},
      {"enabled", msg::kEnabled},
      {"disabled", msg::kDisabled},
      {"data", msg::kData},
      {"cont_data", msg::kContData},
      {"param", msg::kParam},
      {"stats", msg::kStats},
  };
  std::string lower;
  for (char c : text) lower += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const auto& n : kNames) {
    if (lower == n.name) {
      out = n.type;
      return true;
    }
  }
  if (text.empty()) return false;
  char* end = nullptr;
  const long v = std::strtol(text.c_str(), &end, 0);
  if (*end != '\0' || v < -128 || v > 127) return false;
  out = static_cast<int8_t>(v);
  return true;
}

std::optional<AddressMask> parse_address_mask(const std::string& text) {
  if (text == "*") return AddressMask{0, 0};
  if (const auto slash = text.find('/');
      text.rfind("0x", 0) == 0 && slash != std::string::npos && text.find('(') == std::string::npos) {
    char* end = nullptr;
    const unsigned long long value = std::strtoull(text.c_str(), &end, 16);
    if (end != text.c_str() + slash) return std::nullopt;
    const unsigned long long mask = std::strtoull(text.c_str() + slash + 1, &end, 16);
    if (*end != '\0' || value > 0xFFFFFFFFull || mask > 0xFFFFFFFFull) return std::nullopt;
    return AddressMask{static_cast<uint32_t>(value & mask), static_cast<uint32_t>(mask)};
  }
  // Class(sys/inst)[#mbx], each part a number, a name (class) or '*'.
  const auto open = text.find('(');
  const auto slash = text.find('/', open == std::string::npos ? 0 : open);
  const auto close = text.find(')', slash == std::string::npos ? 0 : slash);
  if (open == std::string::npos || slash == std::string::npos || close == std::string::npos || open == 0) {
    return std::nullopt;
  }
  AddressMask m;
  const auto part = [&](const std::string& p, int shift, bool is_class) -> bool {
    if (p == "*") return true;
    long v = -1;
    if (is_class) {
      if (const auto id = class_id(p)) {
        v = *id;
      } else {
        char* end = nullptr;
        v = std::strtol(p.c_str(), &end, 0);
        if (p.empty() || *end != '\0') return false;
      }
    } else {
      char* end = nullptr;
      v = std::strtol(p.c_str(), &end, 10);
      if (p.empty() || *end != '\0') return false;
    }
    if (v < 0 || v > 255) return false;
    m.value |= static_cast<uint32_t>(v) << shift;
    m.mask |= 0xFFu << shift;
    return true;
  };
  if (!part(text.substr(0, open), 16, true) || !part(text.substr(open + 1, slash - open - 1), 24, false) ||
      !part(text.substr(slash + 1, close - slash - 1), 8, false)) {
    return std::nullopt;
  }
  const std::string rest = text.substr(close + 1);
  if (!rest.empty()) {
    if (rest[0] != '#' || !part(rest.substr(1), 0, false)) return std::nullopt;
  }
  return m;
}

}  // namespace rack::tims
