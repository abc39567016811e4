#include "rack/core/component.h"

#include <array>

#include "rack/core/class_description.h"
#include "rack/rt/trace.h"

#include <cstring>
#include <exception>
#include <stdexcept>

namespace rack {

using tims::Address;
using tims::ConstBuffer;
using tims::MessageHeader;
namespace msg = tims::msg;

namespace {
void bump(std::atomic<uint64_t>& c) noexcept {
  // Single writer (the command task).
  c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}
uint8_t message_priority(int sched_priority) noexcept {
  return static_cast<uint8_t>(sched_priority < 0 ? 0 : (sched_priority > 255 ? 255 : sched_priority));
}
}  // namespace

Component::Component() {
  Parameter::Spec spec;
  spec.doc = "GDOS log level: print, error, warning, info or detail (records above it are not logged)";
  spec.choices = {"print", "error", "warning", "info", "detail"};
  log_level_param_ = &params_.declare_string(kLogLevelParam, gdos::describe(gdos::kDefaultLevel), std::move(spec));
}

Component::~Component() = default;

void Component::sync_log_level() noexcept {
  char text[16];
  log_level_param_->copy_string(text, sizeof text);
  if (const auto level = gdos::parse_level(text)) log_source_.set_level(*level);
}

Parameter& Component::declare_component_ref(const std::string& n, const std::string& doc) {
  Parameter::Spec spec;
  spec.doc = doc;
  spec.required = true;
  spec.component_ref = true;
  return params_.declare_string(n, "", std::move(spec));
}

Address Component::resolved(const Parameter& ref) const noexcept {
  for (const auto& [p, a] : refs_) {
    if (p == &ref) return a;
  }
  return Address();
}

void Component::attach(tims::Router& router) {
  router_ = &router;
  log_source_.set_identity(settings_.address, settings_.name);
  sync_log_level();
  command_mailbox_ = std::make_unique<tims::Mailbox>(settings_.address.with_mailbox(0), settings_.command_slots,
                                                     command_slot_size_);
  // Replies to calls made from hooks: GET_DATA replies can be as large as a slot.
  command_reply_mailbox_ = std::make_unique<tims::Mailbox>(settings_.address.with_mailbox(1), 8, 64 * 1024);
  command_reply_mailbox_->set_replies_only(true);  // a request here is refused by the router
  command_endpoint_ = std::make_unique<tims::Endpoint>(router, *command_reply_mailbox_,
                                                       message_priority(settings_.command_task.priority));
  command_buffer_.assign(command_slot_size_ + 8, std::byte{0});
  param_records_.assign(params_.size(), wire::ParamRecord{});
  router.add(*command_mailbox_);
  router.add(*command_reply_mailbox_);
}

void Component::detach() noexcept {
  if (router_ == nullptr) return;
  router_->remove(settings_.address.with_mailbox(0));
  router_->remove(settings_.address.with_mailbox(1));
}

bool Component::run_init(std::string& error) {
  try {
    if (ParameterProblem problem; !check_parameters(ParameterValues(), problem)) {
      error = "parameter '" + (problem.parameter != nullptr ? problem.parameter->name() : std::string("?")) +
              "': " + problem.text;
    } else {
      init();
      return true;
    }
  } catch (const std::exception& e) {
    error = e.what();
  } catch (...) {
    error = "unknown exception";
  }
  init_failed_ = true;
  io_workers_.clear();  // what a failed init() declared does not run
  wire::copy_text(init_error_, ("init() failed: " + error).c_str());
  show_reason(init_error_);
  set_state(ComponentState::kError);
  bump(errors_);
  return false;
}

void Component::add_io_worker(const std::string& name, std::function<void()> body, std::function<void()> stop) {
  if (!body || !stop) throw std::invalid_argument("add_io_worker('" + name + "'): needs a body and a stop");
  io_workers_.push_back(IoWorker{name, std::move(body), std::move(stop)});
}

ComputeWorker& Component::add_compute_worker(const std::string& name) {
  if (name.empty()) throw std::invalid_argument("add_compute_worker: needs a name");
  compute_workers_.push_back(ComputeWorkerDecl{name, std::make_unique<ComputeWorker>()});
  return *compute_workers_.back().worker;
}

void Component::run_cleanup() noexcept {
  try {
    cleanup();
  } catch (...) {
    // Shutting down: nothing left to put in ERROR.
  }
}

void Component::set_state(ComponentState s) noexcept { state_.store(s, std::memory_order_release); }

void Component::request_stop() noexcept {
  stop_.store(true, std::memory_order_release);
  if (command_mailbox_) command_mailbox_->close();
  if (command_reply_mailbox_) command_reply_mailbox_->close();
  stop_data_task();
}

void Component::report_loop_failure() noexcept {
  loop_failed_.store(true, std::memory_order_release);
  command_mailbox_->wake();
}

HookResult Component::call_on() noexcept {
  if (before_on() != HookResult::kOk) return HookResult::kError;  // off() still runs (rule 3)
  try {
    return on();
  } catch (...) {
    return HookResult::kError;
  }
}

void Component::call_off() noexcept {
  try {
    off();
  } catch (...) {
    // off() must not fail; if it throws we are leaving ENABLED anyway.
  }
  after_off();
}

void Component::handle_on(const MessageHeader* request) noexcept {
  if (init_failed_) {
    if (request != nullptr) reply_error(*request, init_error_);
    return;
  }
  if (state() == ComponentState::kEnabled) {
    if (request != nullptr) reply(*request, msg::kOk);
    return;
  }
  const bool retry = request == nullptr;
  if (call_on() == HookResult::kOk) {
    set_state(ComponentState::kEnabled);
    show_reason("");
    entered_enabled();
    if (retry) log_info("ON (retry succeeded): ENABLED");
    else log_info("ON: ENABLED");
    if (request != nullptr) reply(*request, msg::kOk);
    return;
  }
  char reason[96];
  take_error_reason(reason);
  show_reason(reason[0] != '\0' ? reason : "on() failed, no reason given");
  call_off();  // undo what on() did halfway
  const bool first = state() != ComponentState::kError;
  if (first) bump(errors_);
  set_state(ComponentState::kError);
  retry_at_ns_ = rt::monotonic_ns() + settings_.retry_ns;
  // A retry that fails again is detail: the first failure already said so.
  if (first || !retry) {
    log_error("ON: on() failed: %s: ERROR (retrying every %lld ms)", reason[0] != '\0' ? reason : "no reason given",
              static_cast<long long>(settings_.retry_ns / rt::kNsPerMs));
  } else {
    log_detail("retry of on() failed: still ERROR (%s)", reason);
  }
  if (request != nullptr) {
    wire::ErrorText text;
    wire::copy_text(text.text, "on() failed");
    if (reason[0] != '\0') {
      wire::append_text(text.text, ": ");
      wire::append_text(text.text, reason);
    }
    reply_with(*request, msg::kError, text);
  }
}

void Component::handle_off() noexcept {
  const ComponentState before = state();
  if (before == ComponentState::kEnabled) {
    leaving_enabled();
    call_off();
  }
  set_state(ComponentState::kDisabled);
  if (!init_failed_) show_reason("");
  if (before != ComponentState::kDisabled) log_info("OFF: DISABLED (was %s)", describe(before));
}

void Component::go_error() noexcept {
  if (state() != ComponentState::kEnabled) return;
  char reason[96];
  take_error_reason(reason);
  show_reason(reason[0] != '\0' ? reason : "loop() or a command handler failed, no reason given");
  leaving_enabled();
  call_off();
  set_state(ComponentState::kError);
  bump(errors_);
  retry_at_ns_ = rt::monotonic_ns() + settings_.retry_ns;
  log_error("ENABLED -> ERROR (%s); retrying on() every %lld ms",
            reason[0] != '\0' ? reason : "loop() or a command handler failed, no reason given",
            static_cast<long long>(settings_.retry_ns / rt::kNsPerMs));
}

void Component::set_error_reason(const char* reason) noexcept {
  rt::PiLock lock(reason_mutex_);
  wire::copy_text(error_reason_, reason != nullptr ? reason : "");
}

void Component::show_reason(const char* reason) noexcept {
  rt::PiLock lock(reason_mutex_);
  wire::copy_text(shown_reason_, reason);
}

void Component::take_error_reason(char (&out)[96]) noexcept {
  rt::PiLock lock(reason_mutex_);
  std::memcpy(out, error_reason_, sizeof out);
  out[sizeof out - 1] = '\0';
  error_reason_[0] = '\0';
}

HookResult Component::switch_on(Address dest) noexcept {
  alignas(8) std::byte buf[256];
  const auto r = command_endpoint_->call_with_retry(dest, msg::kOn, {}, std::span<std::byte>(buf),
                                                    {settings_.rpc_timeout_ns, settings_.rpc_retries + 1});
  if (r.ok()) return HookResult::kOk;
  // The cause, through the cascade: which dependency, and what it answered.
  char reason[96];
  dest.format(reason, sizeof reason);
  if (r.status != tims::CallStatus::kOk) {
    wire::append_text(reason, " did not answer ON");
  } else if (r.reply.type == msg::kError) {
    wire::append_text(reason, " is in ERROR: ");
    wire::ErrorText text;
    if (wire::read_payload(r.body, tims::body_is_native(r.reply), text)) {
      text.text[sizeof text.text - 1] = '\0';
      wire::append_text(reason, text.text);
    } else {
      wire::append_text(reason, "(no reason)");
    }
  } else {
    wire::append_text(reason, " refused ON");
  }
  set_error_reason(reason);
  return HookResult::kError;
}

void Component::reply(const MessageHeader& request, int8_t type, std::span<const ConstBuffer> body) noexcept {
  (void)command_endpoint_->reply(request, type, body);
}

void Component::reply_error(const MessageHeader& request, const char* reason) noexcept {
  wire::ErrorText text;
  wire::copy_text(text.text, reason);
  reply_with(request, msg::kError, text);
}

void Component::reject_malformed(const MessageHeader& request, const char* reason) noexcept {
  bump(malformed_);
  reply_error(request, reason);
}

void Component::fill_stats(wire::StatsReply& out) const noexcept {
  {
    rt::PiLock lock(reason_mutex_);
    std::memcpy(out.error_reason, shown_reason_, sizeof out.error_reason);
  }
  out.state = static_cast<uint8_t>(state());
  out.data_task = static_cast<uint8_t>(data_task_mode());
  out.period_ns = settings_.period_ns;
  out.commands = commands_.load(std::memory_order_relaxed);
  out.malformed = malformed_.load(std::memory_order_relaxed);
  out.errors = errors_.load(std::memory_order_relaxed);
  if (command_mailbox_) {
    const auto c = command_mailbox_->counters();
    out.command_drops = c.dropped + c.refused + c.too_large + c.truncated;
    out.access_denied = c.denied;
  }
  if (command_reply_mailbox_) out.input_requests += command_reply_mailbox_->refused_requests();
  if (command_endpoint_) out.stale_replies = command_endpoint_->stale_replies();
  const rt::FaultCount cf = command_faults_.last();
  const rt::FaultCount df = data_faults_.last();
  out.faults_measured = static_cast<uint8_t>((cf.measured ? 1 : 0) | (df.measured ? 2 : 0));
  out.command_minor_faults = cf.minor;
  out.command_major_faults = cf.major;
  out.data_minor_faults = df.minor;
  out.data_major_faults = df.major;
}

void Component::fill_listeners(wire::ListenersReply& out) const noexcept {
  out = wire::ListenersReply{};
  out.data_task = static_cast<uint8_t>(data_task_mode());
}

void Component::fill_latency(wire::LatencyHistogram& out) const noexcept {
  out = wire::LatencyHistogram{};
  out.data_task = static_cast<uint8_t>(data_task_mode());
  out.period_ns = settings_.period_ns;
  out.bucket_count = static_cast<uint32_t>(wire::kLatencyBuckets);
  for (std::size_t j = 0; j < wire::kLatencyBuckets; ++j) out.lower_ns[j] = wire::kLatencyLowerNs[j];
}

void Component::sample_faults() const noexcept {
  (void)command_faults_.sample();
  (void)data_faults_.sample();
}

void Component::sample_tasks() noexcept {
  command_sched_.sample(command_faults_.tid());
  data_sched_.sample(data_faults_.tid());
}

void Component::fill_task_record(wire::TasksReply& out, std::size_t i, const rt::TaskSched& sched) const noexcept {
  const TaskSettings& t = i == 0 ? settings_.command_task : settings_.data_task;
  out.configured_priority[i] = t.priority;
  out.configured_cpu[i] = t.cpu;
  out.last_cpu[i] = -1;
  const rt::SchedInfo s = sched.last();
  if (!s.measured) return;
  out.measured[i] = wire::kTaskMeasured;
  out.policy[i] = static_cast<uint8_t>(s.policy);
  out.priority[i] = s.priority;
  out.last_cpu[i] = s.last_cpu;
  for (std::size_t w = 0; w < wire::kTaskCpuWords; ++w) out.affinity[i * wire::kTaskCpuWords + w] = s.affinity[w];
  const int64_t now = rt::monotonic_ns();
  out.sampled_ago_ns[i] = now > s.time_ns ? now - s.time_ns : 0;
  if (s.online_cpus > 0) out.online_cpus = static_cast<uint32_t>(s.online_cpus);
}

void Component::fill_tasks(wire::TasksReply& out) const noexcept {
  out = host_networks_;  // the network_* fields; the rest as a fresh reply
  out.version = wire::kTasksVersion;
  out.data_task = static_cast<uint8_t>(data_task_mode());
  out.task_count = 1;
  fill_task_record(out, 0, command_sched_);
}

void Component::handle_get_param(const MessageHeader& h, std::span<const std::byte> body) noexcept {
  if (body.empty()) {
    for (std::size_t i = 0; i < params_.size(); ++i) params_.at(i).to_record(param_records_[i]);
    const ConstBuffer part{param_records_.data(), param_records_.size() * sizeof(wire::ParamRecord)};
    reply(h, msg::kParam, std::span<const ConstBuffer>(&part, 1));
    return;
  }
  wire::ParamName name;
  if (!wire::read_payload(body, tims::body_is_native(h), name)) {
    return reject_malformed(h, "GET_PARAM: body must be empty or a 32-byte parameter name");
  }
  name.name[sizeof name.name - 1] = '\0';
  const Parameter* p = params_.find(name.name);
  if (p == nullptr) p = params_.renamed(name.name);  // a former name: the record says the new one
  if (p == nullptr) {
    wire::ErrorText text;
    wire::copy_text(text.text, "unknown parameter '");
    wire::append_text(text.text, name.name);
    wire::append_text(text.text, "'");
    reply_with(h, msg::kError, text);
    return;
  }
  wire::ParamRecord record;
  p->to_record(record);
  reply_with(h, msg::kParam, record);
}

void Component::handle_set_param(const MessageHeader& h, std::span<const std::byte> body) noexcept {
  wire::ParamRecord record;
  if (!wire::read_payload(body, tims::body_is_native(h), record)) {
    return reject_malformed(h, "SET_PARAM: body must be one parameter record");
  }
  record.name[sizeof record.name - 1] = '\0';
  Parameter* p = params_.find(record.name);
  // A former name (docs/parameters.md) works as in the host file, with a warning.
  const bool old_name = p == nullptr && (p = params_.renamed(record.name)) != nullptr;
  wire::ErrorText text;
  if (p == nullptr) {
    wire::copy_text(text.text, "unknown parameter '");
    wire::append_text(text.text, record.name);
    wire::append_text(text.text, "'");
    reply_with(h, msg::kError, text);
    return;
  }
  if (p == log_level_param_ && record.kind == static_cast<uint8_t>(wire::ParamKind::kString) &&
      !gdos::parse_level(
          std::string_view(record.string_value, strnlen(record.string_value, sizeof record.string_value)))) {
    wire::copy_text(text.text, "gdosLevel must be one of ");
    wire::append_text(text.text, gdos::kLevelNames);
    reply_with(h, msg::kError, text);
    return;
  }
  // The same rules as the host file and init(): the Spec's (kind, range, choices),
  // then the class's (check_parameters) with the candidate in place; the old value
  // stays unless both accept.
  wire::ParamRecord value;
  const char* why = p->spec().init_only ? "read at start only: change it in the host file and restart rackd"
                                        : p->check_wire(record, value);
  ParameterProblem problem;
  if (why == nullptr && !check_parameters(ParameterValues(*p, value), problem)) why = problem.text;
  if (why == nullptr) why = p->set_from_wire(value);
  if (why != nullptr) {
    wire::copy_text(text.text, record.name);
    wire::append_text(text.text, ": ");
    wire::append_text(text.text, why);
    reply_with(h, msg::kError, text);
    return;
  }
  if (p == log_level_param_) {
    sync_log_level();
    log_print("log level now %s", gdos::describe(log_source_.level()));
  } else {
    switch (static_cast<wire::ParamKind>(value.kind)) {
      case wire::ParamKind::kInt:
        log_info("SET_PARAM %s = %lld from %s", p->name().c_str(), static_cast<long long>(value.int_value), h.source());
        break;
      case wire::ParamKind::kBool:
        log_info("SET_PARAM %s = %s from %s", p->name().c_str(), value.int_value != 0 ? "true" : "false", h.source());
        break;
      case wire::ParamKind::kFloat:
        log_info("SET_PARAM %s = %g from %s", p->name().c_str(), value.float_value, h.source());
        break;
      case wire::ParamKind::kString:
        log_info("SET_PARAM %s = \"%s\" from %s", p->name().c_str(), value.string_value, h.source());
        break;
    }
  }
  if (!old_name) {
    reply(h, msg::kOk);
    return;
  }
  // OK, with the warning as its text (tools print it; older tools ignore the body).
  log_warning("SET_PARAM from %s by the old name '%s': the parameter is now '%s' (rename it: docs/parameters.md)",
              h.source(), record.name, p->name().c_str());
  wire::copy_text(text.text, "parameter '");
  wire::append_text(text.text, record.name);
  wire::append_text(text.text, "' is now '");
  wire::append_text(text.text, p->name().c_str());
  wire::append_text(text.text, "' (the old name still works; rename it: docs/parameters.md)");
  reply_with(h, msg::kOk, text);
}

void Component::handle_get_class(const MessageHeader& h, std::span<const std::byte> body) noexcept {
  ClassPageHeader header;
  std::span<const std::byte> page;
  if (const char* why = class_page(class_description_, class_description_base_, body, tims::body_is_native(h), header,
                                   page)) {
    if (class_description_.empty()) return reply_error(h, why);
    return reject_malformed(h, why);
  }
  const std::array<ConstBuffer, 2> parts{tims::buffer_of(header), ConstBuffer{page.data(), page.size()}};
  reply(h, msg::kClass, parts);
}

void Component::handle(const MessageHeader& h, std::span<const std::byte> body) noexcept {
  bump(commands_);
  if (!h.is_request()) return;  // a late reply or notification: nothing to answer
  switch (h.type) {
    case msg::kOn:
      if (!body.empty()) return reject_malformed(h, "ON takes no body");
      return handle_on(&h);
    case msg::kOff:
      if (!body.empty()) return reject_malformed(h, "OFF takes no body");
      // Answered at once; off() is bounded (STYLE: hooks never block long).
      handle_off();
      return reply(h, msg::kOk);
    case msg::kGetStatus: {
      if (!body.empty()) return reject_malformed(h, "GET_STATUS takes no body");
      const ComponentState s = state();
      return reply(h, s == ComponentState::kEnabled    ? msg::kEnabled
                      : s == ComponentState::kDisabled ? msg::kDisabled
                                                       : msg::kError);
    }
    case msg::kGetParam: return handle_get_param(h, body);
    case msg::kSetParam: return handle_set_param(h, body);
    case msg::kGetClass: return handle_get_class(h, body);
    case msg::kGetStats: {
      if (!body.empty()) return reject_malformed(h, "GET_STATS takes no body");
      wire::StatsReply stats;
      fill_stats(stats);
      return reply_with(h, msg::kStats, stats);
    }
    case msg::kGetListeners: {
      if (!body.empty()) return reject_malformed(h, "GET_LISTENERS takes no body");
      wire::ListenersReply listeners;  // 792 bytes on the command task's stack
      fill_listeners(listeners);
      return reply_with(h, msg::kListeners, listeners);
    }
    case msg::kGetTasks: {
      if (!body.empty()) return reject_malformed(h, "GET_TASKS takes no body");
      wire::TasksReply tasks;  // 680 bytes on the command task's stack
      fill_tasks(tasks);
      return reply_with(h, msg::kTasks, tasks);
    }
    case msg::kGetLatency: {
      if (!body.empty()) return reject_malformed(h, "GET_LATENCY takes no body");
      wire::LatencyHistogram hist;  // 728 bytes on the command task's stack
      fill_latency(hist);
      return reply_with(h, msg::kLatency, hist);
    }
    default: break;
  }
  if (handle_data_request(h, body)) return;
  if (h.type >= msg::kFirstClassCommand) {
    try {
      if (command(h, body) == CommandResult::kHandled) return;
    } catch (...) {
      reply_error(h, "command handler failed");
      go_error();
      return;
    }
  }
  bump(malformed_);
  wire::ErrorText text;
  wire::copy_text(text.text, "unknown command for this component");
  reply_with(h, msg::kError, text);
}

int64_t Component::command_wait_ns() const noexcept {
  if (state() != ComponentState::kError || init_failed_) return tims::Mailbox::kForever;
  const int64_t left = retry_at_ns_ - rt::monotonic_ns();
  return left < 0 ? 0 : left;
}

void Component::command_pass(const tims::Mailbox::Received& r) noexcept {
  if (loop_failed_.exchange(false, std::memory_order_acq_rel)) go_error();
  switch (r.status) {
    case tims::RecvStatus::kOk: {
      // One command is one cycle of the command task: the mode-switch window.
      rt::modeswitch::enter_cycle();
      rt::trace::record(rt::trace::Kind::kCycleStart);
      handle(
          r.header,
          std::span<const std::byte>(command_buffer_).subspan(sizeof(MessageHeader), r.length - sizeof(MessageHeader)));
      rt::trace::record(rt::trace::Kind::kCycleEnd);
      const rt::modeswitch::Verdict verdict = rt::modeswitch::leave_cycle();
      if (verdict.reports > 0) rt::trace::record(rt::trace::Kind::kModeSwitch, verdict.reports);
      if (verdict.abort) go_error();  // abort mode: the component goes to ERROR
      break;
    }
    case tims::RecvStatus::kTooSmall:
      if (r.header.is_request()) reject_malformed(r.header, "request larger than the command buffer");
      break;
    case tims::RecvStatus::kTimeout:
    case tims::RecvStatus::kEmpty:
    case tims::RecvStatus::kClosed: break;
  }
  if (state() == ComponentState::kError && !init_failed_ && rt::monotonic_ns() >= retry_at_ns_) {
    rt::modeswitch::enter_cycle();
    handle_on(nullptr);  // back-off elapsed: retry
    if (rt::modeswitch::leave_cycle().abort) go_error();
  }
}

void Component::run_command_task() noexcept {
  while (!stopping()) {
    const auto r = command_mailbox_->receive(command_buffer_, command_wait_ns());
    if (r.status == tims::RecvStatus::kClosed) break;
    command_pass(r);
  }
}

bool Component::step_commands() noexcept {
  bool any = false;
  for (;;) {
    const auto r = command_mailbox_->receive(command_buffer_, tims::Mailbox::kNonBlocking);
    if (r.status == tims::RecvStatus::kClosed) return any;
    command_pass(r);  // also with nothing received: a loop failure, a retry that is due
    if (r.status != tims::RecvStatus::kOk && r.status != tims::RecvStatus::kTooSmall) return any;
    any = true;
  }
}

}  // namespace rack
