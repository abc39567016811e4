// Which request a TiMS reply answers, for a tool with many requests in flight
// (rack-gui: status, stats, data and class pages of every component, the commands of
// several browsers, a player's 250 PUBLISH a second).
//
// A reply carries its request's 8-bit sequence number, and the answering mailbox as its
// source. Numbered by one counter (Endpoint::send), the numbers wrap every 256 sends:
// a reply that came after its request had timed out was taken by the request that got
// the same number to the same mailbox later, and with more than 255 requests to one
// mailbox in flight two of them held one number.
//
// Here each request to a mailbox gets a number that nothing else to that mailbox holds:
// neither a request still waiting nor one that timed out less than `quarantine_ns` ago
// (its reply may still come). A message is taken only by the request whose destination
// is its source and whose number it carries, and only when it is a reply (type <= 0: a
// request arriving in a reply mailbox answers nothing). A late reply (to a number in
// quarantine) is dropped and counted, and so is one that matches nothing. When every
// number of a mailbox is taken (256 waiting or recently timed out), the request is
// refused (counted) rather than sent with a number that could take another's reply.
//
// Pure code, no I/O (unit-tested on its own). Not RT code; not thread-safe: one owner
// (rack-gui's worker thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <unordered_map>
#include <utility>
#include <vector>

namespace rack::gui {

class ReplyMatcher {
 public:
  explicit ReplyMatcher(int64_t quarantine_ns) : quarantine_ns_(quarantine_ns) {}

  // A sequence number for a request to `dest` (a component address: its command
  // mailbox) known by `token`, waiting until `deadline_ns`; nullopt when none is free.
  [[nodiscard]] std::optional<uint8_t> open(uint32_t dest, uint64_t token, int64_t deadline_ns, int64_t now_ns);
  // The request was not sent after all: its number is free again at once.
  void cancel(uint32_t dest, uint8_t seq);

  enum class Outcome : uint8_t {
    kAnswered,   // the reply of a waiting request: `token`
    kLate,       // the reply of a request that timed out: dropped
    kUnmatched,  // no request to `source` with this number: dropped
    kNotAReply,  // a request (type > 0) in the reply mailbox: dropped
  };
  struct Match {
    Outcome outcome = Outcome::kUnmatched;
    uint64_t token = 0;
  };
  // A message from `source` (a component address) with `seq` and `type`.
  [[nodiscard]] Match match(uint32_t source, uint8_t seq, int8_t type);

  // The requests whose deadline has passed (in the order they were opened); their
  // numbers stay in quarantine until now_ns + quarantine_ns. Frees the numbers whose
  // quarantine has ended.
  [[nodiscard]] std::vector<uint64_t> expire(int64_t now_ns);

  [[nodiscard]] std::size_t waiting() const noexcept { return waiting_; }
  [[nodiscard]] uint64_t answered() const noexcept { return answered_; }
  [[nodiscard]] uint64_t late() const noexcept { return late_; }
  [[nodiscard]] uint64_t unmatched() const noexcept { return unmatched_; }
  [[nodiscard]] uint64_t not_replies() const noexcept { return not_replies_; }
  [[nodiscard]] uint64_t refused() const noexcept { return refused_; }

 private:
  struct Entry {
    uint64_t token = 0;
    uint64_t order = 0;    // when opened (expire's order)
    int64_t until_ns = 0;  // waiting: the deadline; else: the end of its quarantine
    bool waiting = true;
  };
  using Key = std::pair<uint32_t, uint8_t>;  // destination, sequence number
  int64_t quarantine_ns_;
  std::map<Key, Entry> entries_;                // the numbers taken
  std::unordered_map<uint32_t, uint8_t> next_;  // per destination: the number to try first
  uint64_t opened_ = 0;
  std::size_t waiting_ = 0;
  uint64_t answered_ = 0;
  uint64_t late_ = 0;
  uint64_t unmatched_ = 0;
  uint64_t not_replies_ = 0;
  uint64_t refused_ = 0;
};

}  // namespace rack::gui
