#include "rack/core/data_component.h"

#include "rack/rt/trace.h"

#include <algorithm>
#include <cstdio>
#include <climits>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rack {

using tims::Address;
using tims::ConstBuffer;
using tims::MessageHeader;
namespace msg = tims::msg;

namespace {
void bump(std::atomic<uint64_t>& c) noexcept { c.fetch_add(1, std::memory_order_relaxed); }
uint8_t message_priority(int p) noexcept { return static_cast<uint8_t>(p < 0 ? 0 : (p > 255 ? 255 : p)); }
// wake_loop()'s notification: a reply type between the framework's (down to -14) and
// the classes' (from -21 down), which no one answers with.
constexpr int8_t kWakeLoop = -20;
}  // namespace

DataComponentBase::DataComponentBase(DataTaskMode mode, uint32_t payload_size, std::span<const tims::FieldDesc> fields)
    : mode_(mode), payload_size_(payload_size), fields_(fields) {}

void DataComponentBase::attach(tims::Router& router) {
  Component::attach(router);
  const ComponentSettings& settings = this->settings();
  ring_ = std::make_unique<SampleRing>(settings.ring_size, payload_size_);
  data_reply_mailbox_ = std::make_unique<tims::Mailbox>(address().with_mailbox(kDataReplyMailbox), 8, 64 * 1024);
  data_reply_mailbox_->set_replies_only(true);  // a request here is refused by the router
  data_endpoint_ = std::make_unique<tims::Endpoint>(router, *data_reply_mailbox_,
                                                    message_priority(settings.data_task.priority));
  router.add(*data_reply_mailbox_);
  if (input_slot_size_ > 0) {
    input_mailbox_ = std::make_unique<tims::Mailbox>(input_address(), settings.input_slots, input_slot_size_);
    trusted_ = std::make_unique<tims::TrustedSources>(address());
    input_mailbox_->set_trusted_sources(trusted_.get());
    router.add(*input_mailbox_);
  }
  scratch_.assign(sizeof(wire::SampleHeader) + payload_size_ + 8, std::byte{0});
  listeners_.assign(settings.max_listeners, Listener{});
}

void DataComponentBase::stop_data_task() noexcept {
  if (input_mailbox_) input_mailbox_->close();
  if (data_reply_mailbox_) data_reply_mailbox_->close();
}

int64_t DataComponentBase::effective_period_ns() const noexcept {
  if (mode_ == DataTaskMode::kPeriodic) return settings().period_ns;
  return last_interval_ns_.load(std::memory_order_relaxed);
}

uint64_t DataComponentBase::publish_bytes(const void* sample, int64_t time_ns) noexcept {
  const uint64_t seq = ring_->write(time_ns, sample);
  const int64_t prev = last_time_ns_.exchange(time_ns, std::memory_order_relaxed);
  if (prev != 0 && time_ns > prev) last_interval_ns_.store(time_ns - prev, std::memory_order_relaxed);
  bump(published_);
  const wire::SampleHeader sh{time_ns, seq};
  const int64_t now = rt::monotonic_ns();
  rt::PiLock lock(listeners_mutex_);
  for (auto& l : listeners_) {
    if (!l.active) continue;
    if (!l.oneshot && lease_expired(l, now)) {
      drop_listener_locked(l, "subscription lease expired (no GET_CONT_DATA renewal in time)");
      bump(listeners_expired_);
      continue;
    }
    if (l.oneshot) {
      send_sample(l, sh, sample);
      l.active = false;
      continue;
    }
    if (--l.countdown == 0) {
      l.countdown = l.factor;
      send_sample(l, sh, sample);
    }
  }
  return seq;
}

void DataComponentBase::send_sample(const Listener& l, const wire::SampleHeader& sh, const void* payload) noexcept {
  const MessageHeader h = tims::make_header(Address(l.mailbox), address(), msg::kData, l.priority, l.seq,
                                            sizeof sh + payload_size_);
  const ConstBuffer parts[] = {tims::buffer_of(sh), ConstBuffer{payload, payload_size_}};
  if (!tims::delivered(router().send(h, std::span<const ConstBuffer>(parts)))) bump(listener_drops_);
}

void DataComponentBase::drop_listener_locked(Listener& l, const char* why) noexcept {
  wire::ErrorText text;
  wire::copy_text(text.text, why);
  const MessageHeader h = tims::make_header(Address(l.mailbox), address(), msg::kError, l.priority, l.seq, sizeof text);
  const ConstBuffer part = tims::buffer_of(text);
  (void)router().send(h, std::span<const ConstBuffer>(&part, 1));
  l.active = false;
}

void DataComponentBase::drop_listeners() noexcept {
  rt::PiLock lock(listeners_mutex_);
  for (auto& l : listeners_) {
    if (l.active) drop_listener_locked(l, "producer left ENABLED");
  }
}

void DataComponentBase::leaving_enabled() noexcept {
  loop_enabled_.store(false, std::memory_order_seq_cst);
  // Wait for a running loop() to finish (bounded by one loop() call).
  while (in_loop_.load(std::memory_order_seq_cst)) rt::sleep_for(50 * rt::kNsPerUs);
  drop_listeners();
}

void DataComponentBase::entered_enabled() noexcept {
  const int64_t now = rt::monotonic_ns();
  for (auto& port : inputs_) port->received_ns_ = now;    // silence counts from ENABLED
  stream_ended_.store(false, std::memory_order_release);  // a new stream
  inputs_ended_reported_ = false;                         // the data task is gated off until loop_enabled_
  loop_enabled_.store(true, std::memory_order_seq_cst);
  if (input_mailbox_) input_mailbox_->wake();
}

HookResult DataComponentBase::subscribe(Address producer, int64_t period_ns, int64_t* real_period_ns) noexcept {
  if (!trusted_) {
    log_error("subscribe to %s: this class has no input mailbox (use_input_mailbox)", producer);
    return HookResult::kError;
  }
  const Address source = producer.component();
  Subscription* sub = nullptr;
  for (auto& s : subscriptions_) {
    if (s.active && s.producer == source) {
      sub = &s;
      break;
    }
  }
  if (sub == nullptr) {
    for (auto& s : subscriptions_) {
      if (!s.active) {
        sub = &s;
        break;
      }
    }
  }
  // Trusted before the request goes out: the first samples may overtake the reply.
  if (sub == nullptr || !trusted_->trust(source, rt::monotonic_ns())) {
    log_error("subscribe to %s: more than %u producers (or just unsubscribed ones) for one input mailbox", producer,
              static_cast<unsigned>(kMaxSubscriptions));
    return HookResult::kError;
  }
  wire::ContDataRequest req;
  req.period_ns = period_ns;
  req.mailbox = input_address().raw();
  alignas(8) std::byte buf[256];
  const tims::ConstBuffer part = tims::buffer_of(req);
  const auto r = command_endpoint().call_with_retry(source, msg::kGetContData,
                                                    std::span<const tims::ConstBuffer>(&part, 1),
                                                    std::span<std::byte>(buf),
                                                    {settings().rpc_timeout_ns, settings().rpc_retries + 1});
  wire::ContDataReply reply;
  if (r.status != tims::CallStatus::kOk || r.reply.type != msg::kContData ||
      !wire::read_payload(r.body, tims::body_is_native(r.reply), reply)) {
    // The producer may have placed us all the same (a lost reply): what it still
    // sends is late, then forged, and its lease runs out.
    trusted_->retire(source, rt::monotonic_ns());
    sub->active = false;
    char reason[96];
    source.format(reason, sizeof reason);
    wire::append_text(reason, r.status != tims::CallStatus::kOk ? " did not answer GET_CONT_DATA"
                                                                : " refused the subscription (GET_CONT_DATA)");
    set_error_reason(reason);
    return HookResult::kError;
  }
  if (real_period_ns != nullptr) *real_period_ns = reply.period_ns;
  sub->producer = source;
  sub->period_ns = period_ns;
  sub->renew_every_ns = reply.lease_ns > 0 ? reply.lease_ns / 4 : 0;
  sub->renew_at_ns = sub->renew_every_ns > 0 ? rt::monotonic_ns() + sub->renew_every_ns : INT64_MAX;
  sub->ended = false;
  sub->active = true;
  if (sub->renew_at_ns < next_renewal_ns_.load(std::memory_order_relaxed)) {
    next_renewal_ns_.store(sub->renew_at_ns, std::memory_order_relaxed);
  }
  return HookResult::kOk;
}

void DataComponentBase::wake_loop() noexcept {
  // A notification to its own input mailbox (trusted: this component): it wakes a
  // triggered data task, and next_input() skips it (not DATA, ERROR or END_OF_STREAM).
  if (input_mailbox_) (void)command_endpoint().send(input_address(), kWakeLoop, {});
}

void DataComponentBase::unsubscribe(Address producer) noexcept {
  const Address source = producer.component();
  for (auto& s : subscriptions_) {
    if (s.active && s.producer == source) s.active = false;
  }
  if (trusted_) trusted_->retire(source, rt::monotonic_ns());
  wire::StopContDataRequest req;
  req.mailbox = input_address().raw();
  alignas(8) std::byte buf[256];
  (void)command_endpoint().call(source, msg::kStopContData, req, std::span<std::byte>(buf), settings().rpc_timeout_ns);
}

Parameter& DataComponentBase::declare_input_source(const std::string& name, const InputSpec& spec) {
  if (spec.optional)
    return declare_string(name, "", {.doc = spec.doc + " (optional; \"\": none)", .component_ref = true});
  return declare_component_ref(name, spec.doc);
}

void DataComponentBase::add_input(std::unique_ptr<InputPort> port, const InputSpec& spec, std::size_t payload_size) {
  if (inputs_.size() >= kMaxSubscriptions) {
    throw std::invalid_argument("declare_input '" + port->name() + "': more than " + std::to_string(kMaxSubscriptions) +
                                " inputs");
  }
  if (spec.ask_period) {
    const std::string period = port->name() + "_period_ms";
    port->period_param_ = &declare_float(period, spec.period_ms,
                                         {.doc = "the sample period asked of " + port->name() + " (0: every sample)",
                                          .min = 0.0,
                                          .max = 3.6e6,
                                          .unit = "ms"});
    if (spec.old_period_name != nullptr) parameters().add_old_name(spec.old_period_name, period);
  }
  // A class that declared silence_ms itself (Joystick's, for an input it watches by
  // hand) keeps it: one silence_ms per component.
  if (spec.silence_param != SilenceParam::kNone && silence_ == nullptr) silence_ = parameters().find("silence_ms");
  if (spec.silence_param == SilenceParam::kNone) {
    if (spec.watched) {
      throw std::invalid_argument("declare_input '" + port->name() +
                                  "': a watched input needs silence_ms (SilenceParam::kNone is for unwatched ones)");
    }
  } else if (silence_ == nullptr) {
    silence_ = &declare_float("silence_ms", spec.silence_ms,
                              {.doc = "a watched input (source) that sends nothing this long has gone silent",
                               .min = 1.0,
                               .max = 3.6e6,
                               .unit = "ms"});
    timeout_is_silence_ = spec.silence_param == SilenceParam::kSilenceMs;
  }
  if (spec.old_silence_name != nullptr) parameters().add_old_name(spec.old_silence_name, "silence_ms");
  // A slot holds a sample of this input, and a producer's ERROR with its reason (wider
  // than a small sample's DATA: a slot too small for it would lose the ERROR).
  const std::size_t body = std::max(sizeof(wire::SampleHeader) + payload_size, sizeof(wire::ErrorText));
  const auto slot = static_cast<uint32_t>(sizeof(tims::MessageHeader) + body + 64);
  if (slot > input_slot_size_) input_slot_size_ = slot;
  inputs_.push_back(std::move(port));
}

int64_t DataComponentBase::silence_ns() const noexcept {
  return silence_ != nullptr ? std::llround(silence_->get_float() * 1e6) : 0;
}

HookResult DataComponentBase::before_on() noexcept {
  const int64_t now = rt::monotonic_ns();
  for (auto& port : inputs_) {
    InputPort& in = *port;
    in.source_ = resolved(in.source_param_);
    in.granted_period_ns_ = 0;
    in.received_ns_ = now;
    in.samples_ = 0;
    in.malformed_ = 0;
    in.header_ = wire::SampleHeader{};
    if (!in.configured()) continue;
    if (in.cascade_on_ && switch_on(in.source_) != HookResult::kOk) return HookResult::kError;
    const int64_t period = in.period_param_ != nullptr ? std::llround(in.period_param_->get_float() * 1e6) : 0;
    if (subscribe(in.source_, period, &in.granted_period_ns_) != HookResult::kOk) return HookResult::kError;
  }
  return HookResult::kOk;
}

void DataComponentBase::after_off() noexcept {
  for (auto& s : subscriptions_) {
    if (s.active) unsubscribe(s.producer);
  }
}

InputPort* DataComponentBase::input_from(Address source) noexcept {
  for (auto& port : inputs_) {
    if (port->configured() && port->source_ == source) return port.get();
  }
  return nullptr;
}

bool DataComponentBase::take_input(InputPort& port, const MessageHeader& h, std::span<const std::byte> body) noexcept {
  if (!port.decode(h, body)) {
    ++port.malformed_;
    return false;
  }
  port.received_ns_ = rt::monotonic_ns();
  ++port.samples_;
  return true;
}

bool DataComponentBase::subscription_ended(Address producer) const noexcept {
  for (const auto& s : subscriptions_) {
    if (s.active && s.producer == producer) return s.ended;
  }
  return false;
}

bool DataComponentBase::watched_input_silent() noexcept {
  const int64_t limit = silence_ns();
  const int64_t now = rt::monotonic_ns();
  for (const auto& port : inputs_) {
    const InputPort& in = *port;
    if (!in.configured() || !in.watched_ || subscription_ended(in.source_)) continue;
    const int64_t silent = now - in.received_ns_;
    if (silent < limit) continue;
    // The reason of the ERROR this leads to (snprintf of integers allocates nothing).
    char source[40];
    in.source_.format(source, sizeof source);
    char reason[192];  // set_error_reason keeps what fits
    std::snprintf(reason, sizeof reason, "%s (input %s) sent nothing for %lld ms (silence_ms %lld)", source,
                  in.name().c_str(), static_cast<long long>(silent / rt::kNsPerMs),
                  static_cast<long long>(limit / rt::kNsPerMs));
    set_error_reason(reason);
    return true;
  }
  return false;
}

void DataComponentBase::note_input_error(const MessageHeader& header) noexcept {
  char reason[96];
  header.source().component().format(reason, sizeof reason);
  wire::append_text(reason, header.type == msg::kError ? " left ENABLED (its data stopped: it sent ERROR)"
                                                       : " is not available (its data stopped)");
  set_error_reason(reason);
}

void DataComponentBase::send_end_of_stream(uint32_t mailbox, uint8_t priority) noexcept {
  const MessageHeader h = tims::make_header(Address(mailbox), address(), msg::kEndOfStream, priority, 0, 0);
  (void)router().send(h, std::span<const ConstBuffer>());
}

void DataComponentBase::end_stream() noexcept {
  if (stream_ended_.exchange(true, std::memory_order_acq_rel)) return;
  rt::PiLock lock(listeners_mutex_);
  for (const auto& l : listeners_) {
    if (l.active && !l.oneshot) send_end_of_stream(l.mailbox, l.priority);
  }
}

void DataComponentBase::note_end_of_stream(const MessageHeader& header) noexcept {
  const Address source = header.source().component();
  for (auto& s : subscriptions_) {
    if (s.active && s.producer == source) s.ended = true;
  }
  last_good_input_ns_ = rt::monotonic_ns();
  last_ended_ = source;
}

void DataComponentBase::pass_end_on() noexcept {
  // After loop(): what it made of the last input is published before the end.
  if (inputs_ended_reported_ || !inputs_ended()) return;
  inputs_ended_reported_ = true;
  log_info("end of stream: every input ended (the last: %s); no more samples, staying ENABLED", last_ended_);
  end_stream();
}

bool DataComponentBase::inputs_ended() const noexcept {
  bool any = false;
  for (const auto& s : subscriptions_) {
    if (!s.active) continue;
    if (!s.ended) return false;
    any = true;
  }
  return any;
}

void DataComponentBase::renew_due_subscriptions(int64_t now_ns) noexcept {
  if (next_renewal_ns_.load(std::memory_order_relaxed) > now_ns) return;
  int64_t next = INT64_MAX;
  for (auto& s : subscriptions_) {
    if (!s.active || s.renew_every_ns == 0) continue;
    if (s.renew_at_ns <= now_ns) {
      // Fire and forget from the data task: the reply goes to the input mailbox, where
      // a CONT_DATA is skipped and an ERROR or NOT_AVAILABLE ends the subscription
      // (next_input: kError). A renewal lost on the way is one of four per lease.
      wire::ContDataRequest req;
      req.period_ns = s.period_ns;
      req.mailbox = input_address().raw();
      const ConstBuffer part = tims::buffer_of(req);
      (void)data_endpoint().send(s.producer, msg::kGetContData, std::span<const ConstBuffer>(&part, 1),
                                 input_address());
      s.renew_at_ns = now_ns + s.renew_every_ns;
    }
    next = std::min(next, s.renew_at_ns);
  }
  next_renewal_ns_.store(next, std::memory_order_relaxed);
}

void DataComponentBase::renew_gated() noexcept {
  in_loop_.store(true, std::memory_order_seq_cst);
  if (loop_enabled_.load(std::memory_order_seq_cst)) renew_due_subscriptions(rt::monotonic_ns());
  in_loop_.store(false, std::memory_order_seq_cst);
}

void DataComponentBase::report_refused_input() noexcept {
  if (!trusted_) return;
  const tims::TrustedSources::Counters c = trusted_->counters();
  if (c.forged == refused_reported_.forged && c.requests == refused_reported_.requests) return;
  const int64_t now = rt::monotonic_ns();
  if (refused_logged_ns_ != 0 && now - refused_logged_ns_ < rt::kNsPerSec) return;
  log_warning(
      "input: refused %llu message(s) not from a subscribed producer and %llu request(s) sent into the data "
      "mailbox since the last report (the last: type %d from %s)",
      static_cast<unsigned long long>(c.forged - refused_reported_.forged),
      static_cast<unsigned long long>(c.requests - refused_reported_.requests), static_cast<int>(c.last_type),
      Address(c.last_source));
  refused_reported_ = c;
  refused_logged_ns_ = now;
}

bool DataComponentBase::handle_data_request(const MessageHeader& h, std::span<const std::byte> body) noexcept {
  const bool native = tims::body_is_native(h);
  switch (h.type) {
    case msg::kGetData: {
      wire::GetDataRequest req;
      if (body.empty()) req.time_ns = 0;
      else if (!wire::read_payload(body, native, req)) {
        reject_malformed(h, "GET_DATA: body must be empty or an 8-byte time");
        return true;
      }
      auto* sh = reinterpret_cast<wire::SampleHeader*>(scratch_.data());
      const RingLookup res = ring_->read(req.time_ns, 2 * effective_period_ns(), *sh,
                                         scratch_.data() + sizeof(wire::SampleHeader));
      if (res != RingLookup::kOk) {
        reply_error(h, describe(res));
        return true;
      }
      const ConstBuffer part{scratch_.data(), sizeof(wire::SampleHeader) + payload_size_};
      reply(h, msg::kData, std::span<const ConstBuffer>(&part, 1));
      return true;
    }
    case msg::kGetContData: {
      wire::ContDataRequest req;
      if (!wire::read_payload(body, native, req)) {
        reject_malformed(h, "GET_CONT_DATA: body must be a 16-byte period and mailbox");
        return true;
      }
      if (state() != ComponentState::kEnabled) {
        reply_error(h, "not enabled");
        return true;
      }
      const int64_t own = effective_period_ns();
      uint32_t factor = 1;
      if (req.period_ns > 0 && own > 0) {
        const double n = std::round(static_cast<double>(req.period_ns) / static_cast<double>(own));
        factor = n < 1.0 ? 1u : (n > 1e6 ? 1'000'000u : static_cast<uint32_t>(n));
      }
      bool placed = false;
      {
        const int64_t now = rt::monotonic_ns();
        rt::PiLock lock(listeners_mutex_);
        Listener* slot = nullptr;
        for (auto& l : listeners_) {
          if (l.active && !l.oneshot && l.mailbox == req.mailbox) {
            slot = &l;
            break;
          }
        }
        if (slot != nullptr) {
          // A renewal or a new period from the same mailbox: the same listener, never a
          // second one. The same period keeps its place in the reduction.
          if (slot->factor != factor) slot->countdown = factor;
          slot->factor = factor;
          slot->priority = h.priority;
          slot->renewed_ns = now;
          placed = true;
        } else {
          for (auto& l : listeners_) {
            if (!l.active) {
              slot = &l;
              break;
            }
          }
          if (slot == nullptr) {  // full: a listener whose lease ran out gives way
            for (auto& l : listeners_) {
              if (l.active && lease_expired(l, now)) {
                drop_listener_locked(l, l.oneshot ? "no new sample within the lease"
                                                  : "subscription lease expired (no GET_CONT_DATA renewal in time)");
                bump(listeners_expired_);
                if (slot == nullptr) slot = &l;
              }
            }
          }
          if (slot != nullptr) {
            *slot = Listener{req.mailbox, factor, factor, 0, h.priority, false, true, now};
            placed = true;
          }
        }
      }
      if (!placed) {
        reply_error(h, "too many listeners");
        return true;
      }
      wire::ContDataReply rep;
      rep.period_ns = own > 0 ? own * factor : 0;
      rep.lease_ns = settings().lease_ns;
      reply_with(h, msg::kContData, rep);
      // A stream that has ended says so to a new listener (and again on a renewal).
      if (stream_ended()) send_end_of_stream(req.mailbox, h.priority);
      return true;
    }
    case msg::kStopContData: {
      wire::StopContDataRequest req;
      if (!wire::read_payload(body, native, req)) {
        reject_malformed(h, "STOP_CONT_DATA: body must be an 8-byte mailbox");
        return true;
      }
      {
        rt::PiLock lock(listeners_mutex_);
        for (auto& l : listeners_) {
          if (l.active && !l.oneshot && l.mailbox == req.mailbox) l.active = false;
        }
      }
      reply(h, msg::kOk);
      return true;
    }
    case msg::kGetNextData: {
      if (!body.empty()) {
        reject_malformed(h, "GET_NEXT_DATA takes no body");
        return true;
      }
      if (state() != ComponentState::kEnabled) {
        reply_error(h, "not enabled");
        return true;
      }
      bool placed = false;
      {
        rt::PiLock lock(listeners_mutex_);
        for (auto& l : listeners_) {
          if (!l.active) {
            l = Listener{h.src, 1, 1, h.seq, h.priority, true, true, rt::monotonic_ns()};
            placed = true;
            break;
          }
        }
      }
      if (!placed) reply_error(h, "too many listeners");
      return true;  // answered with the next sample
    }
    default: return false;
  }
}

void DataComponentBase::fill_stats(wire::StatsReply& out) const noexcept {
  Component::fill_stats(out);
  const rt::LatencySummary s = stats_.summary();
  out.data.cycles = s.cycles;
  out.data.overruns = s.overruns;
  out.data.samples = s.samples;
  out.data.latency_min_ns = s.min_ns;
  out.data.latency_max_ns = s.max_ns;
  out.data.latency_p50_ns = s.p50_ns;
  out.data.latency_p99_ns = s.p99_ns;
  out.data.latency_p999_ns = s.p999_ns;
  out.data.latency_mean_ns = s.mean_ns;
  const rt::ExecTimeSummary e = exec_stats_.summary();
  out.exec_samples = e.samples;
  out.exec_p50_ns = e.p50_ns;
  out.exec_p99_ns = e.p99_ns;
  out.exec_max_ns = e.max_ns;
  out.published = published_.load(std::memory_order_relaxed);
  out.listener_drops = listener_drops_.load(std::memory_order_relaxed);
  out.listeners_expired = listeners_expired_.load(std::memory_order_relaxed);
  if (data_reply_mailbox_) out.input_requests += data_reply_mailbox_->refused_requests();
  if (trusted_) {
    const tims::TrustedSources::Counters c = trusted_->counters();
    out.input_forged = c.forged;
    out.input_requests += c.requests;
    out.input_late = c.late;
  }
  const int64_t now = rt::monotonic_ns();
  auto* self = const_cast<DataComponentBase*>(this);
  rt::PiLock lock(self->listeners_mutex_);
  uint64_t n = 0;
  for (const auto& l : listeners_) n += l.active && !l.oneshot && !lease_expired(l, now) ? 1u : 0u;
  out.listeners = n;
}

void DataComponentBase::fill_listeners(wire::ListenersReply& out) const noexcept {
  Component::fill_listeners(out);
  const int64_t own = effective_period_ns();
  out.period_ns = own > 0 ? own : 0;
  const int64_t now = rt::monotonic_ns();
  auto* self = const_cast<DataComponentBase*>(this);
  rt::PiLock lock(self->listeners_mutex_);
  for (const auto& l : listeners_) {
    if (!l.active || l.oneshot || lease_expired(l, now)) continue;
    if (out.count < wire::kMaxListenerRecords) {
      const std::size_t i = out.count++;
      out.mailbox[i] = l.mailbox;
      out.factor[i] = l.factor;
      out.listener_period_ns[i] = out.period_ns * static_cast<int64_t>(l.factor);
      out.renewed_ago_ns[i] = now > l.renewed_ns ? now - l.renewed_ns : 0;
    }
    ++out.total;
  }
}

void DataComponentBase::fill_tasks(wire::TasksReply& out) const noexcept {
  Component::fill_tasks(out);
  out.task_count = 2;
  fill_task_record(out, 1, data_sched_);
  out.period_ns[1] = mode_ == DataTaskMode::kPeriodic ? settings().period_ns : 0;
  out.measured_period_ns[1] = measured_period_ns_.load(std::memory_order_relaxed);
}

void DataComponentBase::sample_tasks() noexcept {
  Component::sample_tasks();
  const uint64_t runs = loop_runs_.load(std::memory_order_acquire);  // pairs with the data task's release
  const int64_t started = loop_started_ns_.load(std::memory_order_relaxed);
  if (state() != ComponentState::kEnabled) {
    // Not running: the next window begins at the first sample with a run after ON
    // (started 0: no base yet), so that the time it was off does not count.
    measured_period_ns_.store(0, std::memory_order_relaxed);
    period_base_runs_ = runs;
    period_base_started_ns_ = 0;
    return;
  }
  if (runs == period_base_runs_) {
    // No run since the last sample: a period above a second keeps its last figure
    // until a run comes, an input that went silent shows nothing.
    if (rt::monotonic_ns() - started > 10 * rt::kNsPerSec) measured_period_ns_.store(0, std::memory_order_relaxed);
    return;
  }
  if (period_base_started_ns_ != 0 && started > period_base_started_ns_) {
    measured_period_ns_.store((started - period_base_started_ns_) / static_cast<int64_t>(runs - period_base_runs_),
                              std::memory_order_relaxed);
  }
  period_base_runs_ = runs;
  period_base_started_ns_ = started;
}

// GET_LATENCY's open bucket (>= 10 ms) is the 1-us histogram's last one.
static_assert(wire::kLatencyLowerNs.back() ==
              static_cast<int64_t>(rt::LatencyStats::kBuckets - 1) * rt::LatencyStats::kBucketNs);

void DataComponentBase::fill_latency(wire::LatencyHistogram& out) const noexcept {
  Component::fill_latency(out);
  const rt::LatencySummary s = stats_.summary();
  out.cycles = s.cycles;
  out.overruns = s.overruns;
  out.min_ns = s.min_ns;
  out.max_ns = s.max_ns;
  out.mean_ns = s.mean_ns;
  out.p50_ns = s.p50_ns;
  out.p99_ns = s.p99_ns;
  out.p999_ns = s.p999_ns;
  // samples: the sum of this pass's counts, so that the reply adds up even while the
  // data task records (the summary's pass may have seen a few samples fewer).
  out.samples = stats_.compress(std::span<const int64_t>(out.lower_ns, out.bucket_count),
                                std::span<uint64_t>(out.counts, out.bucket_count));
}

void DataComponentBase::run_one_cycle() noexcept {
  in_loop_.store(true, std::memory_order_seq_cst);
  if (loop_enabled_.load(std::memory_order_seq_cst)) {
    renew_due_subscriptions(rt::monotonic_ns());
    HookResult r = HookResult::kError;
    rt::modeswitch::enter_cycle();  // primary mode: loop() and nothing else
    const int64_t started = rt::monotonic_ns();
    rt::trace::record_at(started, rt::trace::Kind::kCycleStart);
    // GET_TASKS' measured period (sample_tasks()): the data task is the only writer.
    loop_started_ns_.store(started, std::memory_order_relaxed);
    loop_runs_.store(loop_runs_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
    try {
      r = loop();
    } catch (...) {
      r = HookResult::kError;
    }
    const int64_t ended = rt::monotonic_ns();
    exec_stats_.record(ended - started);
    rt::trace::record_at(ended, rt::trace::Kind::kCycleEnd, r == HookResult::kOk ? 0 : 1);
    const rt::modeswitch::Verdict verdict = rt::modeswitch::leave_cycle();
    if (verdict.reports > 0) rt::trace::record(rt::trace::Kind::kModeSwitch, verdict.reports);
    if (verdict.abort) r = HookResult::kError;  // abort mode: to ERROR
    if (r != HookResult::kOk) {
      loop_enabled_.store(false, std::memory_order_seq_cst);
      report_loop_failure();
    } else {
      pass_end_on();
    }
  }
  in_loop_.store(false, std::memory_order_seq_cst);
}

void DataComponentBase::drain_input() noexcept {
  // Disabled: input that still arrives (late samples, ERRORs) is stale.
  while (input_mailbox_->peek(tims::Mailbox::kNonBlocking).status == tims::RecvStatus::kOk) {
    input_mailbox_->peek_end();
  }
}

bool DataComponentBase::input_silent() const noexcept {
  if (inputs_ended()) return false;  // ended streams are quiet, not failing
  const int64_t silent_ns = rt::monotonic_ns() - last_good_input_ns_;
  if (silent_ns < settings().data_timeout_ns) return false;
  // The reason of the ERROR this usually leads to (a set-up value read under its
  // own PI lock: RT-safe; snprintf of integers allocates nothing).
  char reason[96];
  std::snprintf(reason, sizeof reason, "no input for %lld ms (data_task timeout_ms %lld): its producers are silent",
                static_cast<long long>(silent_ns / rt::kNsPerMs),
                static_cast<long long>(settings().data_timeout_ns / rt::kNsPerMs));
  const_cast<DataComponentBase*>(this)->set_error_reason(reason);
  return true;
}

void DataComponentBase::input_malformed(const tims::MessageHeader& header, std::size_t size) noexcept {
  malformed_.fetch_add(1, std::memory_order_relaxed);
  const int64_t now = rt::monotonic_ns();
  if (input_malformed_logged_ns_ != 0 && now - input_malformed_logged_ns_ < rt::kNsPerSec) {
    ++input_malformed_suppressed_;
    return;
  }
  log_warning(
      "input: dropped a DATA message of %u bytes from %s that is not the sample expected (%u more since the "
      "last report)",
      static_cast<unsigned>(size), header.source(), static_cast<unsigned>(input_malformed_suppressed_));
  input_malformed_logged_ns_ = now;
  input_malformed_suppressed_ = 0;
}

// ---- the data task's loop: one body for the thread and for a stepped executor ----

void DataComponentBase::begin_data_task() noexcept {
  const int64_t now = rt::monotonic_ns();
  if (mode_ == DataTaskMode::kPeriodic) {
    const int64_t period = settings().period_ns;
    periodic_ = PeriodicState{};
    periodic_.next = now + period;
    if (const int64_t phase = settings().phase_ns; phase >= 0) {          // phase_ms: on the clock's grid
      periodic_.next = (now - phase) / period * period + phase + period;  // the first grid point after now
    }
    return;
  }
  triggered_ = TriggeredState{};
  triggered_.timeout = settings().data_timeout_ns;
  triggered_.deadline = now + triggered_.timeout;
}

void DataComponentBase::periodic_cycle(int64_t woke_ns) noexcept {
  PeriodicState& p = periodic_;
  const int64_t period = settings().period_ns;
  // The wake-up as the sleep read it on the kernel's return, not a clock read here: after
  // an idle period, reaching this line touches cold pages (this object, the mode-switch
  // slot, this library's code) that cost up to a microsecond on a VM, which is the
  // cycle's work, not the wake-up's (bench/RESULTS.md, "Fifth session").
  stats_.record_latency(woke_ns - p.next);
  rt::trace::record(rt::trace::Kind::kWake, p.next);
  const int64_t cycle_start = rt::monotonic_ns();
  run_one_cycle();
  report_refused_input();
  stats_.record_cycle();
  p.next += period;
  const int64_t now = rt::monotonic_ns();
  if (now >= p.next) {  // overrun: skip the missed deadlines, never burst to catch up
    const int64_t missed = (now - p.next) / period + 1;
    p.next += missed * period;
    stats_.record_overruns(static_cast<uint64_t>(missed));
    rt::modeswitch::note_overrun(static_cast<uint64_t>(missed), now - cycle_start);  // WATCHDOG
    rt::trace::record_at(now, rt::trace::Kind::kOverrun, missed);
    p.unreported += static_cast<uint64_t>(missed);
  }
  // Overruns are reported through GDOS at most once a second, with the count since
  // the last report (a task that overruns every cycle must not flood its ring).
  if (p.unreported > 0 && now >= p.next_report) {
    log_warning("overrun: %llu period(s) of %lld us missed since the last report",
                static_cast<unsigned long long>(p.unreported), static_cast<long long>(period / rt::kNsPerUs));
    p.unreported = 0;
    p.next_report = now + rt::kNsPerSec;
  }
}

DataComponentBase::TriggeredPlan DataComponentBase::triggered_plan() noexcept {
  TriggeredState& t = triggered_;
  // Declared inputs: loop() runs at least every silence_ms (SET_PARAM may change it),
  // so that a silent source is noticed in time.
  if (const int64_t silence = silence_ns(); silence > 0) t.timeout = std::min(settings().data_timeout_ns, silence);
  if (!input_mailbox_) return {TriggeredPlan::kSleep, t.deadline};
  report_refused_input();
  if (!loop_enabled_.load(std::memory_order_seq_cst)) {
    t.was_enabled = false;
    drain_input();
    return {TriggeredPlan::kGatedOff, rt::monotonic_ns() + t.timeout};
  }
  if (!t.was_enabled) {  // just enabled: the timeout starts now
    t.was_enabled = true;
    t.deadline = rt::monotonic_ns() + t.timeout;
    last_good_input_ns_ = rt::monotonic_ns();
  }
  // Wake up for the next renewal too (a silent producer must not let the lease lapse).
  return {TriggeredPlan::kWaitInput, std::min(t.deadline, next_renewal_ns_.load(std::memory_order_relaxed))};
}

bool DataComponentBase::triggered_after(const TriggeredPlan& plan, bool got) noexcept {
  TriggeredState& t = triggered_;
  switch (plan.what) {
    case TriggeredPlan::kGatedOff: return false;
    case TriggeredPlan::kWaitInput:
      if (!got && rt::monotonic_ns() < t.deadline) {  // woken without input: renewal due, or a wake()
        renew_gated();
        return false;
      }
      break;
    case TriggeredPlan::kSleep: break;
  }
  run_one_cycle();
  stats_.record_cycle();
  t.deadline = rt::monotonic_ns() + t.timeout;
  return true;
}

void DataComponentBase::run_data_task() noexcept {
  begin_data_task();
  if (mode_ == DataTaskMode::kPeriodic) {
    while (!stopping()) {
      // Renewals due before the next cycle (a period longer than a quarter lease): in
      // between, so that a slow consumer keeps its subscriptions. Each renewal moves
      // next_renewal_ns_ past now, so this ends.
      for (int64_t r = next_renewal_ns_.load(std::memory_order_relaxed);
           r < periodic_.next && !stopping() && loop_enabled_.load(std::memory_order_seq_cst);
           r = next_renewal_ns_.load(std::memory_order_relaxed)) {
        (void)rt::sleep_until_monotonic(r);
        renew_gated();
      }
      const int64_t woke = rt::sleep_until_monotonic(periodic_.next);
      periodic_cycle(woke);
    }
    return;
  }
  // Triggered: loop() runs when input arrives, or when data_timeout passes without
  // any (so a component notices a silent source). Wake-ups without input do not count.
  while (!stopping()) {
    const TriggeredPlan plan = triggered_plan();
    bool got = false;
    switch (plan.what) {
      case TriggeredPlan::kSleep: (void)rt::sleep_until_monotonic(plan.until_ns); break;
      case TriggeredPlan::kGatedOff: (void)input_mailbox_->wait(triggered_.timeout); break;
      case TriggeredPlan::kWaitInput: {
        const int64_t left = plan.until_ns - rt::monotonic_ns();
        got = left > 0 && input_mailbox_->wait(left);
        break;
      }
    }
    if (stopping()) break;
    (void)triggered_after(plan, got);
  }
}

bool DataComponentBase::step_data() noexcept {
  const int64_t now = rt::monotonic_ns();
  if (mode_ == DataTaskMode::kPeriodic) {
    // As the thread does between cycles: a renewal due before the next deadline.
    if (const int64_t r = next_renewal_ns_.load(std::memory_order_relaxed);
        r <= now && r < periodic_.next && loop_enabled_.load(std::memory_order_seq_cst)) {
      renew_gated();
    }
    if (now < periodic_.next) return false;
    periodic_cycle(now);
    return true;
  }
  const TriggeredPlan plan = triggered_plan();
  switch (plan.what) {
    case TriggeredPlan::kGatedOff: return false;
    case TriggeredPlan::kSleep: return now >= plan.until_ns && triggered_after(plan, false);
    case TriggeredPlan::kWaitInput: {
      const bool got = input_mailbox_->queued() > 0;
      if (!got && now < plan.until_ns) return false;
      return triggered_after(plan, got);
    }
  }
  return false;
}

int64_t DataComponentBase::next_data_step_ns() const noexcept {
  const int64_t renewal = loop_enabled_.load(std::memory_order_seq_cst)
                              ? next_renewal_ns_.load(std::memory_order_relaxed)
                              : INT64_MAX;
  if (mode_ == DataTaskMode::kPeriodic) return std::min(periodic_.next, renewal);
  if (!input_mailbox_) return triggered_.deadline;
  if (!loop_enabled_.load(std::memory_order_seq_cst)) {  // gated off: a pass only drains stale input
    return input_mailbox_->queued() > 0 ? rt::monotonic_ns() : INT64_MAX;
  }
  if (!triggered_.was_enabled || input_mailbox_->queued() > 0) return rt::monotonic_ns();
  return std::min(triggered_.deadline, renewal);
}

}  // namespace rack
