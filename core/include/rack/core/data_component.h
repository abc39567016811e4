// A data component: a component with a data task and a ring of timestamped samples.
//
// The data task is either periodic (clock_nanosleep on absolute CLOCK_MONOTONIC
// deadlines; overruns counted and skipped, never caught up in a burst) or triggered
// (woken by messages in its input mailbox, or after data_timeout without any). It
// calls loop() only while the component is ENABLED.
//
// Served by the framework from the command task: GET_DATA (ring lookup), GET_CONT_DATA
// (listener with reduction factor n = round(requested period / own period); the reply
// carries the real period), STOP_CONT_DATA, GET_NEXT_DATA (one-shot). When the
// component leaves ENABLED, every listener gets an ERROR message and is dropped.
//
// Real-time contract: loop() runs in the data task (RT): no allocation, no non-PI
// locks, no printing, no blocking system calls. publish(), input_mailbox(),
// data_endpoint() and read_sample() are RT-safe. subscribe()/unsubscribe() are
// RT-safe and meant for on()/off() (command task).
#pragma once

#include <atomic>
#include <memory>
#include <span>
#include <vector>

#include "rack/core/component.h"
#include "rack/core/sample_ring.h"
#include "rack/rt/exec_time_stats.h"
#include "rack/rt/latency_stats.h"
#include "rack/rt/pi_mutex.h"

namespace rack {

class DataComponentBase : public Component {
 public:
  [[nodiscard]] DataTaskMode data_task_mode() const noexcept override { return mode_; }
  void fill_stats(wire::StatsReply& out) const noexcept override;
  void fill_latency(wire::LatencyHistogram& out) const noexcept override;
  [[nodiscard]] const SampleRing* ring() const noexcept { return ring_.get(); }
  [[nodiscard]] std::span<const tims::FieldDesc> payload_fields() const noexcept { return fields_; }
  [[nodiscard]] uint32_t payload_size() const noexcept { return payload_size_; }
  [[nodiscard]] const rt::LatencyStats& data_task_stats() const noexcept { return stats_; }

  // Local mailbox numbers of a data component.
  static constexpr uint8_t kDataReplyMailbox = 2;
  static constexpr uint8_t kInputMailbox = 3;

 protected:
  DataComponentBase(DataTaskMode mode, uint32_t payload_size, std::span<const tims::FieldDesc> fields);

  virtual HookResult loop() = 0;

  uint64_t publish_bytes(const void* sample, int64_t time_ns) noexcept;
  // Declares an input mailbox (#3) for subscriptions; constructor only.
  void use_input_mailbox(uint32_t slot_size) { input_slot_size_ = slot_size; }
  [[nodiscard]] tims::Mailbox& input_mailbox() noexcept { return *input_mailbox_; }
  [[nodiscard]] tims::Address input_address() const noexcept {
    return address().with_mailbox(kInputMailbox);
  }
  [[nodiscard]] tims::Endpoint& data_endpoint() noexcept { return *data_endpoint_; }
  [[nodiscard]] int64_t period_ns() const noexcept { return settings().period_ns; }

  // What next_input()/next_sample() found in the input mailbox.
  enum class Input : uint8_t {
    kNone,   // the mailbox is empty
    kData,   // a DATA message (next_sample: a sample that decoded)
    kError,  // a producer sent ERROR: it left ENABLED and dropped this subscription
  };
  // Takes the next message of the input mailbox without blocking. A DATA body goes to
  // `take(header, body)`, which decodes what it wants (read_sample) and returns false
  // only when the body does not fit (wrong size for its source's type): that message
  // is counted as malformed (GET_STATS) and logged at most once a second. Other
  // message types are dropped. `header` is the message's. RT-safe when `take` is.
  template <typename Take>
  [[nodiscard]] Input next_input(tims::MessageHeader& header, Take&& take) noexcept;
  // For a consumer of one sample type: skips (and counts) DATA that does not decode
  // as T; kData with `sh` and `out` filled. RT-safe.
  template <tims::Payload T>
  [[nodiscard]] Input next_sample(wire::SampleHeader& sh, T& out) noexcept;
  // For a triggered loop() that found no usable input (only messages that did not
  // decode, or none at all): true once data_timeout has passed since the last DATA
  // that next_input's `take` accepted (or since the component was enabled): the
  // source is silent, or sends nothing usable, and loop() should return kError. A
  // wake-up by one malformed message alone is skipped, not an error. Data task;
  // RT-safe.
  [[nodiscard]] bool input_silent() const noexcept;

  // From on(): GET_CONT_DATA to `producer` for this component's input mailbox.
  HookResult subscribe(tims::Address producer, int64_t period_ns, int64_t* real_period_ns = nullptr) noexcept;
  // From off(): STOP_CONT_DATA (best effort: the producer may be gone).
  void unsubscribe(tims::Address producer) noexcept;

 private:
  friend class Executor;

  void attach(tims::Router& router) override;
  bool handle_data_request(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept override;
  void leaving_enabled() noexcept override;
  void entered_enabled() noexcept override;
  void stop_data_task() noexcept override;
  void run_data_task() noexcept;
  void run_one_cycle() noexcept;
  void drain_input() noexcept;
  // A DATA message of `size` bytes from `header`'s source did not decode: count, log.
  void input_malformed(const tims::MessageHeader& header, std::size_t size) noexcept;
  int64_t input_malformed_logged_ns_ = 0;   // data task only
  int64_t last_good_input_ns_ = 0;          // data task only: input_silent()
  uint64_t input_malformed_suppressed_ = 0;  // data task only

  struct Listener {
    uint32_t mailbox = 0;
    uint32_t factor = 1;
    uint32_t countdown = 1;
    uint8_t seq = 0;
    uint8_t priority = 0;
    bool oneshot = false;
    bool active = false;
  };
  void send_sample(const Listener& l, const wire::SampleHeader& sh, const void* payload) noexcept;
  void drop_listeners() noexcept;
  [[nodiscard]] int64_t effective_period_ns() const noexcept;

  DataTaskMode mode_;
  uint32_t payload_size_;
  std::span<const tims::FieldDesc> fields_;
  uint32_t input_slot_size_ = 0;
  std::unique_ptr<SampleRing> ring_;
  std::unique_ptr<tims::Mailbox> data_reply_mailbox_;
  std::unique_ptr<tims::Endpoint> data_endpoint_;
  std::unique_ptr<tims::Mailbox> input_mailbox_;
  std::vector<std::byte> scratch_;   // command task: GET_DATA copies
  rt::PiMutex listeners_mutex_;      // command task adds/removes, data task sends
  std::vector<Listener> listeners_;
  rt::LatencyStats stats_;
  rt::ExecTimeStats exec_stats_;  // data task: how long each loop() ran (GET_STATS exec_*)
  // loop() gate. Dekker-style with seq_cst: the command task clears loop_enabled_
  // then waits for in_loop_ false; the data task sets in_loop_ then reads
  // loop_enabled_. One of them must see the other's write, so off() never runs
  // concurrently with loop().
  std::atomic<bool> loop_enabled_{false};
  std::atomic<bool> in_loop_{false};
  std::atomic<int64_t> last_time_ns_{0};
  std::atomic<int64_t> last_interval_ns_{0};
  std::atomic<uint64_t> published_{0}, listener_drops_{0};
};

template <tims::Payload T>
class DataComponent : public DataComponentBase {
 public:
  using Sample = T;

 protected:
  explicit DataComponent(DataTaskMode mode)
      : DataComponentBase(mode, sizeof(T), std::span<const tims::FieldDesc>(tims::fields_of<T>)) {}
  // Writes a sample into the ring and sends it to the listeners. RT-safe.
  uint64_t publish(const T& sample, int64_t time_ns) noexcept { return publish_bytes(&sample, time_ns); }
};

// Reads a DATA message body (SampleHeader + T), converting byte order when the
// sender's differs. false when the size is wrong. RT-safe.
template <tims::Payload T>
[[nodiscard]] bool read_sample(const tims::MessageHeader& h, std::span<const std::byte> body,
                               wire::SampleHeader& header, T& out) noexcept {
  if (body.size() != sizeof(wire::SampleHeader) + sizeof(T)) return false;
  std::memcpy(&header, body.data(), sizeof header);
  std::memcpy(&out, body.data() + sizeof header, sizeof(T));
  if (!tims::body_is_native(h)) {
    tims::swap_fields(tims::fields_of<wire::SampleHeader>, reinterpret_cast<std::byte*>(&header), sizeof header);
    tims::swap_fields(tims::fields_of<T>, reinterpret_cast<std::byte*>(&out), sizeof(T));
  }
  return true;
}

template <typename Take>
DataComponentBase::Input DataComponentBase::next_input(tims::MessageHeader& header, Take&& take) noexcept {
  for (;;) {
    const auto p = input_mailbox().peek(tims::Mailbox::kNonBlocking);
    if (p.status != tims::RecvStatus::kOk) return Input::kNone;
    header = *p.header;
    if (header.type == tims::msg::kError) {
      input_mailbox().peek_end();
      return Input::kError;
    }
    if (header.type != tims::msg::kData) {  // a stray reply: nothing to take
      input_mailbox().peek_end();
      continue;
    }
    const std::size_t size = p.body.size();
    const bool ok = take(static_cast<const tims::MessageHeader&>(header), p.body);
    input_mailbox().peek_end();
    if (ok) {
      last_good_input_ns_ = rt::monotonic_ns();
    } else {
      input_malformed(header, size);
    }
    return Input::kData;
  }
}

template <tims::Payload T>
DataComponentBase::Input DataComponentBase::next_sample(wire::SampleHeader& sh, T& out) noexcept {
  for (;;) {
    tims::MessageHeader h;
    bool decoded = false;
    const Input in = next_input(h, [&](const tims::MessageHeader& mh, std::span<const std::byte> body) {
      decoded = read_sample(mh, body, sh, out);
      return decoded;
    });
    if (in != Input::kData || decoded) return in;
  }
}

}  // namespace rack
