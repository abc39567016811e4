// A data component: a component with a data task and a ring of timestamped samples.
//
// The data task is either periodic (clock_nanosleep on absolute CLOCK_MONOTONIC
// deadlines; overruns counted and skipped, never caught up in a burst) or triggered
// (woken by messages in its input mailbox, or after data_timeout without any). It
// calls loop() only while the component is ENABLED. A stepped executor (tests,
// rack/core/stepper.h) runs the same loop body without the waits, on a virtual clock.
//
// Served by the framework from the command task: GET_DATA (ring lookup), GET_CONT_DATA
// (listener with reduction factor n = round(requested period / own period); the reply
// carries the real period and the lease), STOP_CONT_DATA, GET_NEXT_DATA (one-shot),
// GET_LISTENERS (who subscribes now, wire::ListenersReply: the live data flows).
// When the component leaves ENABLED, every listener gets an ERROR message and is
// dropped.
//
// Trust (the input mailbox, #3): a consumer's input mailbox accepts replies and
// notifications (DATA, ERROR, ...) only from the producers it subscribed to with
// subscribe() and has not unsubscribed from, and from the component itself. The
// router refuses everything else before it takes a slot (rack/tims/trusted_sources.h):
// a sample or ERROR from any other address is counted as forged, one from a producer
// unsubscribed less than 2 s ago as late; a request (GET_STATUS, ...) sent into a data
// mailbox is counted and answered NOT_AVAILABLE (at most 10 a second), as RACK answers
// a request to a mailbox that serves none. Nothing refused wakes the data task or
// changes the component's state. The counts are in GET_STATS (input_forged,
// input_requests, input_late) and the data task logs them (warning) at most once a
// second. The table holds tims::TrustedSources::kCapacity producers: no allocation.
// The reply mailboxes (#1 of the command task, #2 of the data task) take no request
// either: refused silently, counted with input_requests.
//
// End of stream: a producer whose data has ended for good while it stays ENABLED (a
// replay at the end of its log) calls end_stream(): every listener, and every one that
// subscribes later, gets END_OF_STREAM (tims::msg::kEndOfStream) instead of silence.
// A consumer takes it in next_input() (it is not DATA, nor an ERROR): that
// subscription is over without a failure. Once every producer it subscribed to has
// ended, input_silent() stays false (no ERROR after data_timeout, no retry every
// second), inputs_ended() is true, and after its next loop() (which publishes what it
// made of the last input) GDOS says so once (info) and the consumer ends its own
// stream: the end travels down the pipeline behind the last sample, and every
// component stays ENABLED and quiet. Switching the producer OFF and ON starts a new stream.
//
// Leases: a listener (GET_CONT_DATA) holds its slot for ComponentSettings::lease_ns
// (host file: data_task.lease_ms, default 10 s) after its last GET_CONT_DATA. A
// GET_CONT_DATA from the same mailbox renews and replaces it (new period, same slot,
// no duplicate). A listener not renewed in time gets an ERROR ("subscription lease
// expired") and is dropped, at the next sample or when a new listener needs its slot;
// so a subscriber that died (a killed `rackctl watch`) frees its slot within one
// lease. subscribe() learns the lease from the CONT_DATA reply and the data task
// renews every lease / 4 without waiting for the answer: the renewal's reply goes to
// the input mailbox (CONT_DATA is skipped there; an ERROR or NOT_AVAILABLE answer
// comes out of next_input() as kError: the subscription is gone). Listeners on a host
// that expires are dropped sooner, by the transport's STOP_CONT_DATA
// (rack/tims/lcm_transport.h).
//
// Declared inputs: a consumer declares each stream it reads in its constructor,
//
//   chassis_(declare_input<interfaces::ChassisData>("chassis", {.doc = "the Chassis to integrate"}))
//
// which declares the component-ref parameter `chassis` (optional ones may be ""),
// with InputSpec::ask_period the parameter `chassis_period_ms` (the period asked of
// the source; 0: every sample), once per component the parameter `silence_ms`, and
// sizes the input mailbox. The framework then, on every ON (also a retry after
// ERROR), switches each configured source on and subscribes, in declaration order,
// before on(); unsubscribes after off(); and loop() takes what arrived with
//
//   const Received r = receive([&](const InputPort& in) { ... chassis_.value() ... });
//   if (r.failed) return HookResult::kError;
//
// which calls the handler once per sample, in arrival order across inputs, with the
// input it came from (its value() and sample_header() hold the sample). A sample that
// does not decode as its input's type is counted and logged (GET_STATS malformed),
// never delivered. r.failed: a producer sent ERROR (it left ENABLED; InputSpec::
// fail_on_error), or a watched input sent nothing for silence_ms (an END_OF_STREAM is
// not silence); the error reason is set. r.errors: producers of inputs that do not
// fail on an ERROR left ENABLED (a trajectory writer's source: its input has ended). A
// triggered data task wakes at least every silence_ms so that silence is noticed
// without input. A source that sends one of several types is declared with them all,
//
//   obstacles_(declare_input<Scan2dData, LadarData>("obstacles", {...}))   // InputOneOf
//   if (obstacles_.holds<LadarData>()) use(obstacles_.value<LadarData>());
//
// A class with a silence limit of its own keeps it (InputSpec::silence_param).
//
// Real-time contract: loop() runs in the data task (RT): no allocation, no non-PI
// locks, no printing, no blocking system calls. publish(), input_mailbox(),
// data_endpoint(), read_sample(), receive() and the InputPort accessors are RT-safe.
// subscribe()/unsubscribe() are RT-safe and meant for on()/off() (command task).
// declare_input() is for the constructor only (it allocates).
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <type_traits>
#include <vector>

#include "rack/core/component.h"
#include "rack/core/sample_ring.h"
#include "rack/rt/exec_time_stats.h"
#include "rack/rt/latency_stats.h"
#include "rack/rt/pi_mutex.h"
#include "rack/tims/trusted_sources.h"

namespace rack {

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

// Where a component's silence limit comes from (InputSpec::silence_param). The first
// declaration that declares silence_ms decides what the host file's data_task.timeout_ms
// means for the class.
enum class SilenceParam : uint8_t {
  kSilenceMs,      // the parameter silence_ms; data_task.timeout_ms is its former name (loaded with a warning)
  kSilenceMsOnly,  // silence_ms; data_task.timeout_ms stays the triggered task's wake-up (the class had a
                   // silence_ms of its own before it declared its inputs: Scan3D)
  kNone,           // no parameter from this input (it must not be watched): the class judges its silence
                   // by a parameter of its own (Joystick's obstacle_timeout_ms)
};

// What a declared input is (DataComponentBase::declare_input).
struct InputSpec {
  std::string doc;            // the source parameter's doc: what the source is
  bool optional = false;      // the parameter may be "" (the default): no such input then
  bool cascade_on = true;     // switch the source on before subscribing (cascading ON)
  bool ask_period = false;    // declare "<name>_period_ms": the period asked of the source
  double period_ms = 0.0;     // its default (0: every sample)
  bool watched = true;        // silent for silence_ms: receive() fails (the component ERRORs)
  bool fail_on_error = true;  // the source's ERROR (it left ENABLED) fails receive()
  // The default of the component's silence_ms (the first declaration that declares it).
  double silence_ms = 1000.0;
  SilenceParam silence_param = SilenceParam::kSilenceMs;
  // Former names of the parameters, accepted with a warning (docs/parameters.md).
  const char* old_period_name = nullptr;   // of "<name>_period_ms"
  const char* old_silence_name = nullptr;  // of "silence_ms"
};

// One declared input. The framework fills it; the component reads it from loop()
// (data task). RT-safe accessors.
class InputPort {
 public:
  virtual ~InputPort() = default;
  InputPort(const InputPort&) = delete;
  InputPort& operator=(const InputPort&) = delete;
  [[nodiscard]] const std::string& name() const noexcept { return source_param_.name(); }
  // The parameter that names the source (any thread: parameters are thread-safe).
  [[nodiscard]] const Parameter& source_parameter() const noexcept { return source_param_; }
  // The source it subscribes to (resolved at ON); raw() == 0: an optional input not
  // configured. Valid from before on() on.
  [[nodiscard]] tims::Address source() const noexcept { return source_; }
  [[nodiscard]] bool configured() const noexcept { return source_.raw() != 0; }
  // The period the source granted (its CONT_DATA reply), 0 when it did not say.
  [[nodiscard]] int64_t granted_period_ns() const noexcept { return granted_period_ns_; }
  // The newest sample's header (time, sequence) and its arrival (monotonic ns; ON
  // before the first sample). Data task.
  [[nodiscard]] const wire::SampleHeader& sample_header() const noexcept { return header_; }
  [[nodiscard]] int64_t time_ns() const noexcept { return header_.time_ns; }
  [[nodiscard]] int64_t received_ns() const noexcept { return received_ns_; }
  [[nodiscard]] uint64_t samples() const noexcept { return samples_; }  // since ON
  // DATA messages from its source that did not decode (wrong size), since ON: each is
  // also counted in GET_STATS malformed and logged (at most once a second). Data task.
  [[nodiscard]] uint64_t malformed() const noexcept { return malformed_; }

 protected:
  InputPort(Parameter& source, const InputSpec& spec) noexcept
      : source_param_(source),
        cascade_on_(spec.cascade_on),
        watched_(spec.watched),
        fail_on_error_(spec.fail_on_error) {}
  // Decodes a DATA body into the port's sample; false: the wrong size.
  virtual bool decode(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept = 0;
  wire::SampleHeader header_{};

 private:
  friend class DataComponentBase;
  Parameter& source_param_;
  Parameter* period_param_ = nullptr;
  bool cascade_on_;
  bool watched_;
  bool fail_on_error_;
  tims::Address source_;
  int64_t granted_period_ns_ = 0;
  int64_t received_ns_ = 0;
  uint64_t samples_ = 0;
  uint64_t malformed_ = 0;
};

// A declared input of samples of type T. The sample lives here (allocated at
// construction: large scans stay off the data task's stack).
template <tims::Payload T>
class InputOf final : public InputPort {
 public:
  InputOf(Parameter& source, const InputSpec& spec) : InputPort(source, spec), value_(std::make_unique<T>()) {}
  // The newest sample (data task). Mutable: loop() may work on it in place.
  [[nodiscard]] const T& value() const noexcept { return *value_; }
  [[nodiscard]] T& value() noexcept { return *value_; }

 private:
  bool decode(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept override {
    return read_sample(h, body, header_, *value_);
  }
  std::unique_ptr<T> value_;
};

namespace detail {
template <typename... Ts>
constexpr bool sizes_differ() noexcept {
  constexpr std::size_t kSizes[] = {sizeof(Ts)...};
  for (std::size_t i = 0; i < sizeof...(Ts); ++i) {
    for (std::size_t j = i + 1; j < sizeof...(Ts); ++j) {
      if (kSizes[i] == kSizes[j]) return false;
    }
  }
  return true;
}
}  // namespace detail

// A declared input whose source sends samples of one of several types (Joystick's
// obstacles: a Scan2D's or a Ladar's scans; Scan3D's odometry: an Odometry's or a
// Position's poses). A sample is taken as the type whose size it has (the sizes
// differ: checked at compile time); one of no type's size is malformed. holds<T>()
// says which type the newest sample is, value<T>() holds the newest sample of type T.
// Each sample lives here (allocated at construction). Data task; RT-safe.
template <tims::Payload... Ts>
class InputOneOf final : public InputPort {
  static_assert(sizeof...(Ts) >= 2, "an input of one type is an InputOf<T>");
  static_assert(detail::sizes_differ<Ts...>(), "the types of an InputOneOf must differ in size");

 public:
  InputOneOf(Parameter& source, const InputSpec& spec) : InputPort(source, spec), values_(std::make_unique<Ts>()...) {}
  template <typename T>
  [[nodiscard]] bool holds() const noexcept {
    static_assert(index_of<T>() < sizeof...(Ts), "T is not one of the input's types");
    return held_ == index_of<T>();
  }
  template <typename T>
  [[nodiscard]] const T& value() const noexcept {
    return *std::get<std::unique_ptr<T>>(values_);
  }
  template <typename T>
  [[nodiscard]] T& value() noexcept {
    return *std::get<std::unique_ptr<T>>(values_);
  }

 private:
  template <typename T>
  static constexpr std::size_t index_of() noexcept {
    constexpr bool kSame[] = {std::is_same_v<T, Ts>...};
    for (std::size_t i = 0; i < sizeof...(Ts); ++i) {
      if (kSame[i]) return i;
    }
    return sizeof...(Ts);
  }
  bool decode(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept override {
    return (decode_as<Ts>(h, body) || ...);
  }
  template <typename T>
  bool decode_as(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept {
    if (!read_sample(h, body, header_, value<T>())) return false;
    held_ = index_of<T>();
    return true;
  }
  std::tuple<std::unique_ptr<Ts>...> values_;
  std::size_t held_ = sizeof...(Ts);  // none yet
};

// The port declare_input<T, More...> makes: InputOf<T>, or InputOneOf<T, More...>.
template <tims::Payload T, tims::Payload... More>
using InputFor = std::conditional_t<sizeof...(More) == 0, InputOf<T>, InputOneOf<T, More...>>;

class DataComponentBase : public Component {
 public:
  [[nodiscard]] DataTaskMode data_task_mode() const noexcept override { return mode_; }
  void fill_stats(wire::StatsReply& out) const noexcept override;
  void fill_latency(wire::LatencyHistogram& out) const noexcept override;
  // GET_LISTENERS: the continuous listeners whose lease runs (the first
  // wire::kMaxListenerRecords of them), read under listeners_mutex_ (priority
  // inheritance) without allocation: RT-safe, the command task answers it.
  void fill_listeners(wire::ListenersReply& out) const noexcept override;
  // GET_TASKS: adds the data task's record (its timer period, the mean interval of
  // its loop() runs as sample_tasks() last measured it). RT-safe.
  void fill_tasks(wire::TasksReply& out) const noexcept override;
  // Also measures the mean interval between loop() runs since the previous call
  // (0 when loop() did not run twice: a disabled component, a silent input). Non-RT thread.
  void sample_tasks() noexcept override;
  [[nodiscard]] const SampleRing* ring() const noexcept { return ring_.get(); }
  [[nodiscard]] std::span<const tims::FieldDesc> payload_fields() const noexcept { return fields_; }
  [[nodiscard]] uint32_t payload_size() const noexcept { return payload_size_; }
  [[nodiscard]] const rt::LatencyStats& data_task_stats() const noexcept { return stats_; }
  // The class declares its inputs (declare_input): the framework subscribes them and
  // owns the parameter silence_ms.
  [[nodiscard]] bool declares_inputs() const noexcept { return !inputs_.empty(); }
  // The host file's data_task.timeout_ms is the former name of this class's silence_ms
  // (SilenceParam::kSilenceMs): the host file loader maps it there, with a warning.
  [[nodiscard]] bool timeout_is_silence() const noexcept { return silence_ != nullptr && timeout_is_silence_; }

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
  [[nodiscard]] tims::Address input_address() const noexcept { return address().with_mailbox(kInputMailbox); }
  [[nodiscard]] tims::Endpoint& data_endpoint() noexcept { return *data_endpoint_; }
  [[nodiscard]] int64_t period_ns() const noexcept { return settings().period_ns; }

  // What next_input()/next_sample() found in the input mailbox.
  enum class Input : uint8_t {
    kNone,   // the mailbox is empty
    kData,   // a DATA message (next_sample: a sample that decoded)
    kError,  // a producer sent ERROR (it left ENABLED, or refused a renewal) or its
             // mailbox is gone (NOT_AVAILABLE to a renewal): this subscription is over
  };
  // Takes the next message of the input mailbox without blocking. Only messages of
  // trusted producers (and of this component) get there (see "Trust" above). A DATA
  // body goes to `take(header, body)`, which decodes what it wants (read_sample) and
  // returns false only when the body does not fit (wrong size for its source's type):
  // that message is counted as malformed (GET_STATS) and logged at most once a
  // second. Other replies (CONT_DATA of a renewal, a component's own wake-ups) are
  // skipped. `header` is the message's. RT-safe when `take` is.
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
  // When it returns true it also sets the error reason ("no input for N ms").
  [[nodiscard]] bool input_silent() const noexcept;
  // Every producer this component subscribed to has ended its stream (END_OF_STREAM,
  // see "End of stream" above): no more input will come. Data task; RT-safe.
  [[nodiscard]] bool inputs_ended() const noexcept;
  // For a producer, data task: its stream has ended for good (see "End of stream").
  // Every listener gets END_OF_STREAM now, a later one right after its CONT_DATA,
  // until the component leaves ENABLED. Idempotent. RT-safe.
  void end_stream() noexcept;
  [[nodiscard]] bool stream_ended() const noexcept { return stream_ended_.load(std::memory_order_acquire); }

  // From on(): trusts `producer` in the input mailbox, then GET_CONT_DATA to it for
  // this component's input mailbox; the data task renews it every lease / 4 while
  // ENABLED. kError (logged) without an input mailbox, with kMaxSubscriptions
  // producers already, or when the producer refuses or does not answer.
  HookResult subscribe(tims::Address producer, int64_t period_ns, int64_t* real_period_ns = nullptr) noexcept;
  // Command task: makes a triggered data task run loop() soon, without input (after a
  // Handoff::post() that loop() should see at once: a request it answers). RT-safe.
  void wake_loop() noexcept;

  // From off(): STOP_CONT_DATA (best effort: the producer may be gone); no more
  // renewals, and the producer's messages are no longer trusted (late ones are
  // dropped quietly for a grace period).
  void unsubscribe(tims::Address producer) noexcept;
  static constexpr std::size_t kMaxSubscriptions = tims::TrustedSources::kCapacity;

  // ---- declared inputs (see "Declared inputs" above) ----
  // Constructor only (allocates): declares the source parameter `name` (and the
  // period and silence parameters the spec asks for) and sizes the input mailbox.
  // declare_input<T> gives an InputOf<T>; with more types, declare_input<A, B> an
  // InputOneOf<A, B> (a source that sends one of them).
  template <tims::Payload T, tims::Payload... More>
  InputFor<T, More...>& declare_input(const std::string& name, const InputSpec& spec) {
    Parameter& source = declare_input_source(name, spec);
    auto port = std::make_unique<InputFor<T, More...>>(source, spec);
    InputFor<T, More...>& out = *port;
    add_input(std::move(port), spec, std::max({sizeof(T), sizeof(More)...}));
    return out;
  }
  // What receive() found.
  struct Received {
    uint32_t samples = 0;  // delivered to the handler
    bool failed = false;   // a producer's ERROR, or a watched input silent: return kError (reason set)
    // ERRORs of inputs that do not fail on them (InputSpec::fail_on_error false),
    // skipped: those producers left ENABLED and their subscriptions are over.
    uint32_t errors = 0;
  };
  // Takes every message in the input mailbox and calls `on_sample(const InputPort&)`
  // for each sample that decoded, in arrival order; stops at a producer's ERROR
  // (InputSpec::fail_on_error; otherwise it is skipped). Then checks the watched
  // inputs' silence. Data task (loop()); RT-safe when `on_sample` is.
  template <typename OnSample>
  [[nodiscard]] Received receive(OnSample&& on_sample) noexcept;
  // The component's silence limit (the parameter silence_ms), 0 without declared inputs.
  [[nodiscard]] int64_t silence_ns() const noexcept;

 private:
  friend class Executor;
  friend class Stepper;

  Parameter& declare_input_source(const std::string& name, const InputSpec& spec);
  void add_input(std::unique_ptr<InputPort> port, const InputSpec& spec, std::size_t payload_size);
  HookResult before_on() noexcept override;  // declared inputs: cascading ON, subscribe
  void after_off() noexcept override;        // every subscription still active: stop it
  [[nodiscard]] InputPort* input_from(tims::Address source) noexcept;
  // The data task's input step for one DATA message of a declared input's source.
  [[nodiscard]] bool take_input(InputPort& port, const tims::MessageHeader& h,
                                std::span<const std::byte> body) noexcept;
  // A watched input silent for silence_ms (sets the error reason). Data task.
  [[nodiscard]] bool watched_input_silent() noexcept;
  [[nodiscard]] bool subscription_ended(tims::Address producer) const noexcept;
  std::vector<std::unique_ptr<InputPort>> inputs_;
  Parameter* silence_ = nullptr;
  bool timeout_is_silence_ = true;

  void attach(tims::Router& router) override;
  bool handle_data_request(const tims::MessageHeader& h, std::span<const std::byte> body) noexcept override;
  void leaving_enabled() noexcept override;
  void entered_enabled() noexcept override;
  void stop_data_task() noexcept override;
  // The data task. The thread (run_data_task) and a stepped executor (step_data,
  // rack/core/stepper.h) run the same pieces: begin_data_task() once, then for a
  // periodic task periodic_cycle(woke) at each deadline (`woke`: the monotonic time the
  // sleep returned, rt::sleep_until_monotonic's; the wake-up latency is woke - deadline),
  // for a triggered one
  // triggered_plan() (what to wait for, until when) and triggered_after() (a cycle
  // when input came or the deadline passed). Data task (RT-safe).
  void run_data_task() noexcept;
  void begin_data_task() noexcept;
  void periodic_cycle(int64_t woke_ns) noexcept;
  struct TriggeredPlan {
    enum What : uint8_t { kWaitInput, kSleep, kGatedOff } what;  // kSleep: no input mailbox
    int64_t until_ns;                                            // monotonic
  };
  [[nodiscard]] TriggeredPlan triggered_plan() noexcept;
  bool triggered_after(const TriggeredPlan& plan, bool got) noexcept;  // true: loop() ran
  // Stepped executors: one pass of the data task at the present (virtual) time, without
  // waiting: a periodic task runs one cycle when its deadline has come, a triggered
  // one when input waits or its timeout has passed. true: a cycle ran.
  bool step_data() noexcept;
  // When step_data() next has something to do (monotonic ns; INT64_MAX: nothing until
  // a command or input comes). For stepped executors.
  [[nodiscard]] int64_t next_data_step_ns() const noexcept;
  struct PeriodicState {
    int64_t next = 0;         // the next deadline
    uint64_t unreported = 0;  // overruns not reported yet
    int64_t next_report = 0;  // overruns are reported at most once a second
  };
  struct TriggeredState {
    int64_t timeout = 0;  // data_timeout, or silence_ms when shorter
    bool was_enabled = false;
    int64_t deadline = 0;  // loop() runs by then without input
  };
  PeriodicState periodic_;    // data task only
  TriggeredState triggered_;  // data task only
  void run_one_cycle() noexcept;
  void drain_input() noexcept;
  // A DATA message of `size` bytes from `header`'s source did not decode: count, log.
  void input_malformed(const tims::MessageHeader& header, std::size_t size) noexcept;
  int64_t input_malformed_logged_ns_ = 0;    // data task only
  int64_t last_good_input_ns_ = 0;           // data task only: input_silent()
  uint64_t input_malformed_suppressed_ = 0;  // data task only

  struct Listener {
    uint32_t mailbox = 0;
    uint32_t factor = 1;
    uint32_t countdown = 1;
    uint8_t seq = 0;
    uint8_t priority = 0;
    bool oneshot = false;
    bool active = false;
    int64_t renewed_ns = 0;  // its last GET_CONT_DATA (GET_NEXT_DATA): the lease starts here
  };
  void send_sample(const Listener& l, const wire::SampleHeader& sh, const void* payload) noexcept;
  // Sends `l` an ERROR with `why` (its seq: a one-shot's request is answered) and frees
  // it. listeners_mutex_ held.
  void drop_listener_locked(Listener& l, const char* why) noexcept;
  [[nodiscard]] bool lease_expired(const Listener& l, int64_t now_ns) const noexcept {
    return now_ns - l.renewed_ns > settings().lease_ns;
  }
  void drop_listeners() noexcept;

  // A subscription of this component (consumer side). Written by the command task in
  // on()/off() while loop() is gated off, read and renewed by the data task while it
  // is gated on (the loop gate below), so never both at once.
  struct Subscription {
    tims::Address producer;
    int64_t period_ns = 0;
    int64_t renew_every_ns = 0;  // lease / 4; 0: the producer grants no lease
    int64_t renew_at_ns = 0;
    bool active = false;
    bool ended = false;  // END_OF_STREAM received (data task)
  };
  // Data task: `header` is an END_OF_STREAM; marks its producer's subscription ended.
  void note_end_of_stream(const tims::MessageHeader& header) noexcept;
  // Data task, after a loop() that succeeded: once every input has ended, logs it and
  // ends this component's own stream (after what loop() published of the last input).
  void pass_end_on() noexcept;
  tims::Address last_ended_;  // data task: the producer whose end came last
  void send_end_of_stream(uint32_t mailbox, uint8_t priority) noexcept;
  // Data task, loop gate held: GET_CONT_DATA to every producer whose renewal is due.
  // Sets the error reason "<producer> left ENABLED" (or NOT_AVAILABLE) for an input ERROR.
  void note_input_error(const tims::MessageHeader& header) noexcept;
  void renew_due_subscriptions(int64_t now_ns) noexcept;
  // Data task: takes the loop gate and renews (a triggered task woken for it alone).
  void renew_gated() noexcept;
  // Data task: logs refused input (forged, requests) at most once a second.
  void report_refused_input() noexcept;
  std::array<Subscription, kMaxSubscriptions> subscriptions_{};
  std::unique_ptr<tims::TrustedSources> trusted_;  // with the input mailbox
  // The earliest renewal due (relaxed: a wake-up hint for the triggered data task;
  // the renewal itself re-checks every subscription). INT64_MAX: none.
  std::atomic<int64_t> next_renewal_ns_{INT64_MAX};
  tims::TrustedSources::Counters refused_reported_{};  // data task only
  int64_t refused_logged_ns_ = 0;                      // data task only
  [[nodiscard]] int64_t effective_period_ns() const noexcept;

  DataTaskMode mode_;
  uint32_t payload_size_;
  std::span<const tims::FieldDesc> fields_;
  uint32_t input_slot_size_ = 0;
  std::unique_ptr<SampleRing> ring_;
  std::unique_ptr<tims::Mailbox> data_reply_mailbox_;
  std::unique_ptr<tims::Endpoint> data_endpoint_;
  std::unique_ptr<tims::Mailbox> input_mailbox_;
  std::vector<std::byte> scratch_;  // command task: GET_DATA copies
  rt::PiMutex listeners_mutex_;     // command task adds/removes, data task sends
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
  // loop() runs and the start of the latest (data task writes, sample_tasks() reads:
  // the start is stored before the count, the count with release, so a reader that
  // sees run n sees its start or a later one: within one interval).
  std::atomic<uint64_t> loop_runs_{0};
  std::atomic<int64_t> loop_started_ns_{0};
  // sample_tasks()' state (its thread only) and result (relaxed: one value, any reader).
  uint64_t period_base_runs_ = 0;
  int64_t period_base_started_ns_ = 0;
  std::atomic<int64_t> measured_period_ns_{0};
  std::atomic<uint64_t> published_{0}, listener_drops_{0}, listeners_expired_{0};
  // end_stream() was called since the last ENABLED (release: the command task then
  // tells a new listener; acquire in stream_ended()).
  std::atomic<bool> stream_ended_{false};
  bool inputs_ended_reported_ = false;  // data task
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

template <typename Take>
DataComponentBase::Input DataComponentBase::next_input(tims::MessageHeader& header, Take&& take) noexcept {
  for (;;) {
    const auto p = input_mailbox().peek(tims::Mailbox::kNonBlocking);
    if (p.status != tims::RecvStatus::kOk) return Input::kNone;
    header = *p.header;
    if (header.type == tims::msg::kError || header.type == tims::msg::kNotAvailable) {
      input_mailbox().peek_end();
      note_input_error(header);  // the error reason, should loop() now fail
      return Input::kError;
    }
    if (header.type == tims::msg::kEndOfStream) {  // a producer's stream ended: not a failure
      input_mailbox().peek_end();
      note_end_of_stream(header);
      continue;
    }
    if (header.type != tims::msg::kData) {  // a renewal's CONT_DATA, a wake-up: nothing to take
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

template <typename OnSample>
DataComponentBase::Received DataComponentBase::receive(OnSample&& on_sample) noexcept {
  Received r;
  for (;;) {
    tims::MessageHeader header;
    InputPort* port = nullptr;
    bool decoded = false;
    const Input in = next_input(header, [&](const tims::MessageHeader& h, std::span<const std::byte> body) {
      port = input_from(h.source().component());
      if (port == nullptr) return true;  // a late sample of a former source: not ours now, not malformed
      decoded = take_input(*port, h, body);
      return decoded;
    });
    if (in == Input::kNone) break;
    if (in == Input::kError) {
      const InputPort* from = input_from(header.source().component());
      if (from == nullptr || from->fail_on_error_) {
        r.failed = true;  // the reason is set (next_input): the retry re-subscribes
        return r;
      }
      ++r.errors;
      continue;
    }
    if (port != nullptr && decoded) {
      ++r.samples;
      on_sample(static_cast<const InputPort&>(*port));
    }
  }
  if (watched_input_silent()) r.failed = true;
  return r;
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
