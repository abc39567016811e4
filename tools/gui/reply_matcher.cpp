#include "reply_matcher.h"

#include <algorithm>

namespace rack::gui {

std::optional<uint8_t> ReplyMatcher::open(uint32_t dest, uint64_t token, int64_t deadline_ns, int64_t now_ns) {
  uint8_t& next = next_[dest];
  for (int tried = 0; tried < 256; ++tried) {
    const auto seq = static_cast<uint8_t>(next + tried);
    const auto it = entries_.find({dest, seq});
    if (it != entries_.end()) {
      if (it->second.waiting || it->second.until_ns > now_ns) continue;
      entries_.erase(it);  // its quarantine is over
    }
    entries_.emplace(Key{dest, seq}, Entry{token, opened_++, deadline_ns, true});
    ++waiting_;
    next = static_cast<uint8_t>(seq + 1);
    return seq;
  }
  ++refused_;
  return std::nullopt;
}

void ReplyMatcher::cancel(uint32_t dest, uint8_t seq) {
  const auto it = entries_.find({dest, seq});
  if (it == entries_.end()) return;
  if (it->second.waiting) --waiting_;
  entries_.erase(it);
}

ReplyMatcher::Match ReplyMatcher::match(uint32_t source, uint8_t seq, int8_t type) {
  Match m;
  const auto it = entries_.find({source, seq});
  if (it == entries_.end()) {
    ++unmatched_;
    return m;
  }
  if (type > 0) {
    ++not_replies_;
    m.outcome = Outcome::kNotAReply;
    return m;
  }
  if (it->second.waiting) {
    m.outcome = Outcome::kAnswered;
    m.token = it->second.token;
    --waiting_;
    ++answered_;
  } else {
    m.outcome = Outcome::kLate;  // its one reply came: the number is free again
    ++late_;
  }
  entries_.erase(it);
  return m;
}

std::vector<uint64_t> ReplyMatcher::expire(int64_t now_ns) {
  std::vector<std::pair<uint64_t, uint64_t>> expired;  // (order, token)
  for (auto it = entries_.begin(); it != entries_.end();) {
    Entry& e = it->second;
    if (e.waiting && e.until_ns <= now_ns) {
      expired.emplace_back(e.order, e.token);
      e.waiting = false;
      e.until_ns = now_ns + quarantine_ns_;
      --waiting_;
      ++it;
    } else if (!e.waiting && e.until_ns <= now_ns) {
      it = entries_.erase(it);
    } else {
      ++it;
    }
  }
  std::sort(expired.begin(), expired.end());
  std::vector<uint64_t> tokens;
  tokens.reserve(expired.size());
  for (const auto& [order, token] : expired) tokens.push_back(token);
  return tokens;
}

}  // namespace rack::gui
