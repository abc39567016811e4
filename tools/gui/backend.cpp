// rack-gui's backend (backend.h, backend_impl.h): the worker thread, TiMS requests and
// their replies, the browsers' requests (handle) and the public Backend.
#include "backend_impl.h"

namespace rack::gui {

void Backend::Impl::dispatch(const tims::Mailbox::Received& got, std::span<const std::byte> buf) {
  const ReplyMatcher::Match m = replies.match(got.header.source().component().raw(), got.header.seq, got.header.type);
  if (m.outcome != ReplyMatcher::Outcome::kAnswered) {
    const std::lock_guard lock(counters_mutex);
    if (m.outcome == ReplyMatcher::Outcome::kLate) ++counters.late_replies;
    else ++counters.unmatched_replies;
    return;
  }
  const auto it = reply_handlers.find(m.token);
  if (it == reply_handlers.end()) return;
  ReplyHandler done = std::move(it->second);
  reply_handlers.erase(it);
  Reply r;
  r.header = got.header;
  r.body = buf.subspan(sizeof(tims::MessageHeader), got.length - sizeof(tims::MessageHeader));
  done(&r);
}

void Backend::Impl::receive_replies(int64_t wait_ns) {
  auto got = reply_mailbox.receive(buffer, wait_ns);
  while (got.status == tims::RecvStatus::kOk) {
    dispatch(got, buffer);
    got = reply_mailbox.receive(buffer, tims::Mailbox::kNonBlocking);
  }
  for (auto img = image_mailbox.receive(image_buffer, tims::Mailbox::kNonBlocking); img.status == tims::RecvStatus::kOk;
       img = image_mailbox.receive(image_buffer, tims::Mailbox::kNonBlocking)) {
    dispatch(img, image_buffer);
  }
  for (tims::Mailbox* m : {&small_stream_mailbox, &stream_mailbox}) {
    for (auto st = m->receive(buffer, tims::Mailbox::kNonBlocking); st.status == tims::RecvStatus::kOk;
         st = m->receive(buffer, tims::Mailbox::kNonBlocking)) {
      stream_sample(st, buffer);
    }
  }
  const int64_t now = rt::monotonic_ns();
  std::vector<ReplyHandler> expired;
  for (const uint64_t token : replies.expire(now)) {
    const auto it = reply_handlers.find(token);
    if (it == reply_handlers.end()) continue;
    expired.push_back(std::move(it->second));
    reply_handlers.erase(it);
  }
  if (!expired.empty()) {
    const std::lock_guard lock(counters_mutex);
    counters.timeouts += expired.size();
  }
  for (auto& done : expired) done(nullptr);
}

std::string Backend::Impl::failure(const Reply* r, const std::string& what, Address dest) const {
  if (r == nullptr) return address_text(dest) + ": no reply to " + what + " in time (host gone or busy?)";
  if (r->header.type == msg::kNotAvailable) return address_text(dest) + ": not available (no such component running)";
  if (r->header.type == msg::kError) return address_text(dest) + ": " + what + " refused: " + error_reason(r->body);
  return address_text(dest) + ": " + what + ": unexpected reply " + std::to_string(r->header.type);
}

void Backend::Impl::defer(int64_t delay_ns, std::function<void()> f) {
  deferred.emplace_back(rt::monotonic_ns() + delay_ns, std::move(f));
}

void Backend::Impl::run_deferred() {
  const int64_t now = rt::monotonic_ns();
  std::vector<std::function<void()>> due;
  for (auto it = deferred.begin(); it != deferred.end();) {
    if (it->first <= now) {
      due.push_back(std::move(it->second));
      it = deferred.erase(it);
    } else {
      ++it;
    }
  }
  for (auto& f : due) f();
}

void Backend::Impl::handle(uint64_t client, const Request& r) {
  switch (r.op) {
    case Op::kSwitch: {
      const Address a = r.component;
      request(
          a, r.on ? msg::kOn : msg::kOff,
          [this, client, r, a](const Reply* rep) {
            const bool ok = rep != nullptr && rep->header.type == msg::kOk;
            result(client, r, ok,
                   ok ? address_text(a) + (r.on ? " on" : " off") : failure(rep, r.on ? "ON" : "OFF", a));
            poll_status();
          },
          r.on ? kOnTimeoutNs : 0);
      break;
    }
    case Op::kAllOff: {
      // Reverse order: hosts in reverse, each host's components against its host
      // file's order, so consumers go off before their producers (as rackd does).
      std::vector<const Component*> list;
      for (const auto& [raw, c] : components) {
        if (c.system == r.system) list.push_back(&c);
      }
      std::sort(list.begin(), list.end(), [](const Component* a, const Component* b) {
        return a->host_key != b->host_key ? a->host_key > b->host_key : a->order > b->order;
      });
      auto order = std::make_shared<std::vector<Address>>();
      for (const Component* c : list) order->push_back(c->info.address);
      if (order->empty()) {
        result(client, r, false, "robot " + std::to_string(r.system) + " has no components");
        break;
      }
      all_off_step(client, r, order, 0, std::make_shared<std::vector<std::string>>());
      break;
    }
    case Op::kGetParams: {
      const Address a = r.component;
      request(a, msg::kGetParam, [this, client, r, a](const Reply* rep) {
        if (rep == nullptr || rep->header.type != msg::kParam || rep->body.size() % sizeof(wire::ParamRecord) != 0) {
          result(client, r, false, failure(rep, "GET_PARAM", a));
          return;
        }
        json list = json::array();
        for (std::size_t i = 0; i < rep->body.size() / sizeof(wire::ParamRecord); ++i) {
          wire::ParamRecord p;
          if (wire::read_payload(rep->body.subspan(i * sizeof p, sizeof p), rep->native(), p)) {
            list.push_back(param_json(p));
          }
        }
        send_to(client, dump(json{{"type", "params"}, {"component", address_text(a)}, {"params", list}}));
        result(client, r, true, address_text(a) + ": " + std::to_string(list.size()) + " parameters");
      });
      break;
    }
    case Op::kSetParam: {
      // The kind first (the component's), then the checked value.
      const Address a = r.component;
      wire::ParamName name;
      wire::copy_text(name.name, r.param_name.c_str());
      request(a, msg::kGetParam, name, [this, client, r, a](const Reply* rep) {
        wire::ParamRecord p;
        if (rep == nullptr || rep->header.type != msg::kParam || !wire::read_payload(rep->body, rep->native(), p)) {
          result(client, r, false, failure(rep, "GET_PARAM " + r.param_name, a));
          return;
        }
        const std::string bad = check_param_value(r.param_value, p);
        if (!bad.empty()) {
          {
            const std::lock_guard lock(counters_mutex);
            ++counters.malformed;
            ++counters.refused[static_cast<std::size_t>(Refusal::kBadValue)];
          }
          result(client, r, false,
                 address_text(a) + " parameter '" + r.param_name + "' (" +
                     rack::describe(static_cast<wire::ParamKind>(p.kind)) + "): " + bad + "; nothing was sent");
          return;
        }
        // By the name given: a former name (docs/parameters.md) works as in the host
        // file, and the component's OK then carries the warning that names the new one.
        const std::string now = param_text(p.name, sizeof p.name);
        wire::ParamRecord sent = p;
        wire::copy_text(sent.name, r.param_name.c_str());
        request(a, msg::kSetParam, sent, [this, client, r, a, p, now](const Reply* rep2) {
          const bool ok = rep2 != nullptr && rep2->header.type == msg::kOk;
          std::string warning;
          if (ok && !rep2->body.empty()) {
            const auto* text = reinterpret_cast<const char*>(rep2->body.data());
            warning = " (warning: " + param_text(text, rep2->body.size()) + ")";
          }
          result(client, r, ok,
                 ok ? address_text(a) + ": " + now + " = " + dump(param_json(p)["value"]) + warning
                    : failure(rep2, "SET_PARAM " + r.param_name, a));
        });
      });
      break;
    }
    case Op::kSetDestination: {
      const auto pilot = find(r.system, kPilot);
      if (!pilot) {
        result(client, r, false, "robot " + std::to_string(r.system) + " has no Pilot");
        break;
      }
      const Address a = *pilot;
      const std::string why = send_command(
          a, "SET_DESTINATION", json{{"x", r.x}, {"y", r.y}}, [this, client, r, a](const Reply* rep) {
            const bool ok = rep != nullptr && rep->header.type == msg::kOk;
            if (ok) release_joystick(r.system);  // the Pilot takes the chassis back
            result(client, r, ok, ok ? address_text(a) + ": destination set" : failure(rep, "SET_DESTINATION", a));
          });
      if (!why.empty()) result(client, r, false, why);
      break;
    }
    case Op::kFollowPath: {
      const auto pilot = find(r.system, kPilot);
      if (!pilot) {
        result(client, r, false, "robot " + std::to_string(r.system) + " has no Pilot");
        break;
      }
      const Address a = *pilot;
      const std::string why = send_command(a, "FOLLOW_PATH", json::object(), [this, client, r, a](const Reply* rep) {
        const bool ok = rep != nullptr && rep->header.type == msg::kOk;
        if (ok) release_joystick(r.system);
        result(client, r, ok, ok ? address_text(a) + ": following the path" : failure(rep, "FOLLOW_PATH", a));
      });
      if (!why.empty()) result(client, r, false, why);
      break;
    }
    case Op::kGetClass: {
      const Address a = r.component;
      const ClassInfo* info = described(a);
      if (info != nullptr) {
        send_to(client, class_message(a.system(), *info->desc, address_text(a)));
        result(client, r, true, address_text(a) + ": class " + info->desc->class_name + " described");
      } else if (class_infos[a.raw() & 0xFFFF0000u].failed) {
        result(client, r, false, address_text(a) + ": its class description could not be read (see rack-gui's log)");
      } else {
        class_waiters[a.raw() & 0xFFFF0000u].emplace_back(client, r);  // answered when it arrives
      }
      break;
    }
    case Op::kCommand:
    case Op::kCommandJson: class_command(client, r); break;
    case Op::kTrace: trace(client, r); break;
    case Op::kSetPose: set_pose(client, r); break;
    case Op::kJoystick: joystick(client, r); break;
    case Op::kJoystickRelease: {
      Robot& robot = robots[r.system];
      if (robot.joystick_owner == client || robot.joystick_owner == 0) stop_joystick(r.system);
      result(client, r, true, "joystick released: robot stopped");
      break;
    }
    case Op::kSubscribe: subscribe(client, r); break;
    case Op::kUnsubscribe: {
      const auto it = streams.find(r.component.raw());
      const bool had = it != streams.end() && it->second.clients.erase(client) > 0;
      if (had && it->second.clients.empty()) stop_stream(r.component.raw());
      result(client, r, had,
             address_text(r.component) + (had ? ": unsubscribed" : ": this client did not subscribe to it"));
      break;
    }
  }
}

void Backend::Impl::run_worker() {
  int64_t next_round = rt::monotonic_ns();
  int64_t next_discovery = next_round;
  uint64_t round = 0;
  while (running.load()) {
    // Client requests and closed clients, handed over by the server's thread.
    std::deque<std::pair<uint64_t, Request>> work;
    std::vector<uint64_t> closed;
    {
      const std::lock_guard lock(queue_mutex);
      work.swap(queue);
      closed.swap(closed_clients);
    }
    for (const uint64_t c : closed) {
      for (auto& [s, robot] : robots) {
        if (robot.joystick_owner == c) stop_joystick(s);
      }
      std::vector<uint32_t> idle;
      for (auto& [raw, st] : streams) {
        if (st.clients.erase(c) > 0 && st.clients.empty()) idle.push_back(raw);
      }
      for (const uint32_t raw : idle) stop_stream(raw);
    }
    for (auto& [client, req] : work) {
      if (resolve_component(client, req)) handle(client, req);
    }
    check_dead_man();
    run_deferred();

    const int64_t now = rt::monotonic_ns();
    if (now >= next_discovery) {
      transport.request_discovery();
      next_discovery = now + rt::kNsPerSec;
    }
    if (now >= next_round) {
      next_round = now + int64_t{config.poll_ms} * rt::kNsPerMs;
      refresh_hosts();
      poll_status();
      if (round % 5 == 0) {
        poll_stats();
        poll_latency();
      }
      poll_data(round);
      maintain_streams();
      poll_maps();
      std::string snapshot = components_message();
      {
        const std::lock_guard lock(greet_mutex);
        last_components = snapshot;
      }
      broadcast(std::move(snapshot));
      ++round;
    }
    receive_replies(10 * rt::kNsPerMs);
  }
}

void Backend::Impl::greet(uint64_t client) {
  send_to(client, dump(json{{"type", "hello"}, {"version", 1}, {"lcm", config.lcm_url}}));
  const std::lock_guard lock(greet_mutex);
  if (!last_components.empty()) send_to(client, last_components);
  for (const auto& [k, m] : class_messages) send_to(client, m);
  for (const auto& [s, m] : map_messages) send_to(client, m);
  if (std::string g = gdos.snapshot(); !g.empty()) send_to(client, std::move(g));
  if (std::string r = reports.snapshot(); !r.empty()) send_to(client, std::move(r));
}

void Backend::Impl::refuse(uint64_t client, const ParseError& e) {
  std::string line;
  {
    const std::lock_guard lock(counters_mutex);
    ++counters.malformed;
    ++counters.refused[static_cast<std::size_t>(e.reason)];
    const int64_t now = rt::monotonic_ns();
    if (now - last_refusal_log_ns >= rt::kNsPerSec) {
      last_refusal_log_ns = now;
      line = "rack-gui: client " + std::to_string(client) + ": refused (" + describe(e.reason) + "): " + e.message;
      if (refusals_not_logged > 0) line += " (and " + std::to_string(refusals_not_logged) + " more not logged)";
      refusals_not_logged = 0;
    } else {
      ++refusals_not_logged;
    }
  }
  if (!line.empty()) std::fprintf(stderr, "%s\n", line.c_str());
  send_to(client, error_message(e));
}

Backend::Backend(BackendConfig config, Sink sink) : impl_(std::make_unique<Impl>(std::move(config), std::move(sink))) {}
Backend::~Backend() = default;
void Backend::start() { impl_->start(); }
void Backend::stop() { impl_->stop(); }

void Backend::submit(uint64_t client, std::string_view text) noexcept {
  try {
    auto parsed = parse_request(text);
    if (auto* e = std::get_if<ParseError>(&parsed)) {
      impl_->refuse(client, *e);
      return;
    }
    {
      const std::lock_guard lock(impl_->queue_mutex);
      if (impl_->queue.size() < kMaxQueuedRequests) {
        impl_->queue.emplace_back(client, std::get<Request>(std::move(parsed)));
        // The worker waits for replies up to 10 ms at a time: woken, it takes the
        // request now (a player's PUBLISH after PUBLISH need not wait that out).
        impl_->reply_mailbox.wake();
        return;
      }
    }
    // A client sending faster than the robots answer: refused, not queued without end.
    const auto& r = std::get<Request>(parsed);
    impl_->refuse(client, ParseError{r.id,
                                     std::string(op_name(r.op)) + ": " + std::to_string(kMaxQueuedRequests) +
                                         " requests are waiting already; send fewer",
                                     Refusal::kBusy});
  } catch (const std::exception& e) {  // out of memory: the message is lost, rack-gui goes on
    std::fprintf(stderr, "rack-gui: client %llu: message of %zu bytes dropped: %s\n",
                 static_cast<unsigned long long>(client), text.size(), e.what());
  }
}

void Backend::refused(uint64_t client, Refusal reason, const std::string& message) noexcept {
  try {
    impl_->refuse(client, ParseError{std::nullopt, message, reason});
  } catch (const std::exception&) {  // out of memory: only the answer is lost
  }
}

void Backend::client_closed(uint64_t client) {
  const std::lock_guard lock(impl_->queue_mutex);
  impl_->closed_clients.push_back(client);
}

void Backend::greet(uint64_t client) { impl_->greet(client); }

Backend::Counters Backend::counters() const {
  Counters c;
  {
    const std::lock_guard lock(impl_->counters_mutex);
    c = impl_->counters;
  }
  for (const tims::Mailbox* m : {&impl_->stream_mailbox, &impl_->small_stream_mailbox}) {
    const tims::MailboxCounters mc = m->counters();
    c.stream_lost += mc.refused + mc.dropped + mc.too_large;
  }
  return c;
}

}  // namespace rack::gui
