// rack-gui's backend: class commands (one handler, two body encoders), live traces,
// all off, set pose, the joystick (backend_impl.h).
#include "backend_impl.h"

namespace rack::gui {

void Backend::Impl::trace(uint64_t client, const Request& r) {
  const tims::HostInfo* host = nullptr;
  std::string names;
  const auto all = transport.hosts();
  for (const auto& h : all) {
    if (h.system != r.system || h.role != tims::NodeRole::kExecutor) continue;
    names += (names.empty() ? "" : ", ") + h.host;
    if (!r.host.empty() && h.host != r.host) continue;
    if (host != nullptr && r.host.empty()) {
      result(client, r, false, "robot " + std::to_string(r.system) + " has several hosts (" + names + "...): name one");
      return;
    }
    host = &h;
  }
  if (host == nullptr) {
    result(client, r, false,
           "robot " + std::to_string(r.system) + ": no host" +
               (r.host.empty() ? std::string() : " named '" + r.host + "'") + " answers" +
               (names.empty() ? std::string() : " (hosts: " + names + ")"));
    return;
  }
  const Address exec = host->executor;
  const Address t = Address::make(exec.system(), exec.class_id(), exec.instance(), rtrace::kTraceMailbox);
  const std::string host_name = host->host;
  rtrace::TraceStartRequest req;
  req.duration_ns = static_cast<int64_t>(r.duration_s * 1e9);
  wire::copy_text(req.names, "all");
  request(t, rtrace::kTraceStart, req, [this, client, r, t, host_name, req](const Reply* rep) {
    if (rep == nullptr || rep->header.type != msg::kOk) {
      result(client, r, false, failure(rep, "TRACE_START", t));
      return;
    }
    auto text = std::make_shared<std::string>();
    const int64_t give_up = rt::monotonic_ns() + req.duration_ns + 30 * rt::kNsPerSec;
    defer(req.duration_ns,
          [this, client, r, t, host_name, text, give_up] { trace_read(client, r, t, host_name, text, give_up); });
  });
}

void Backend::Impl::trace_read(uint64_t client, const Request& r, Address t, const std::string& host_name,
                               const std::shared_ptr<std::string>& text, int64_t give_up) {
  if (rt::monotonic_ns() > give_up) {
    result(client, r, false, host_name + ": the trace was not ready 30 s after its end");
    return;
  }
  rtrace::TraceReadRequest rr;
  rr.offset = text->size();
  request(t, rtrace::kTraceRead, rr, [this, client, r, t, host_name, text, give_up](const Reply* rep) {
    if (rep == nullptr || rep->header.type != msg::kOk) {
      result(client, r, false, failure(rep, "TRACE_READ", t));
      return;
    }
    // The reply checked as rackctl checks it (rack::trace::decode_chunk, fuzz_trace_reply;
    // the total of the earlier chunks is not kept here: each chunk must fit its own).
    const rtrace::DecodedChunk chunk = rtrace::decode_chunk(rep->body, !rep->native(), text->size(), 0);
    const rtrace::TraceChunkHeader& head = chunk.header;
    if (!chunk.ok) {
      result(client, r, false, host_name + " (" + rep->header.source().str() + "): " + chunk.error);
      return;
    }
    const auto state = static_cast<rtrace::TraceState>(head.state);
    const auto again = [&](int64_t delay) {
      defer(delay,
            [this, client, r, t, host_name, text, give_up] { trace_read(client, r, t, host_name, text, give_up); });
    };
    if (state == rtrace::TraceState::kRecording) {
      again(std::clamp<int64_t>(head.remaining_ns, 10 * rt::kNsPerMs, 200 * rt::kNsPerMs));
      return;
    }
    if (state != rtrace::TraceState::kReady || head.total > (100u << 20)) {
      result(client, r, false, host_name + ": TRACE_READ: the trace was discarded or is over 100 MiB");
      return;
    }
    text->append(reinterpret_cast<const char*>(chunk.bytes.data()), chunk.bytes.size());
    if (text->size() < head.total) {
      again(0);
      return;
    }
    const json doc = json::parse(*text, nullptr, false);
    if (doc.is_discarded()) {
      result(client, r, false, host_name + ": the trace is not JSON (" + std::to_string(text->size()) + " bytes)");
      return;
    }
    send_to(
        client,
        dump(json{
            {"type", "trace"}, {"host", host_name}, {"system", r.system}, {"dropped", head.dropped}, {"json", *text}}));
    result(client, r, true,
           host_name + ": trace of " + json(r.duration_s).dump() + " s, " + std::to_string(text->size()) + " bytes");
  });
}

std::string Backend::Impl::text_fields_body(const Request& r, const rack::TypeDescription* type,
                                            std::vector<std::byte>& body) {
  if (type == nullptr) return r.fields.empty() ? std::string() : "it takes no fields";
  const std::vector<tims::FieldDesc> table = type->field_table();
  body.assign(type->size, std::byte{0});
  for (const auto& [key, text] : r.fields) {
    const tims::FieldDesc* field = nullptr;
    for (const auto& f : table) {
      if (key == f.name) field = &f;
    }
    const std::string why = field == nullptr ? "no such field in " + type->name
                                             : rack::set_field_from_text(*field, body, text);
    if (!why.empty()) return "field '" + key + "': " + why;
  }
  return "";
}

std::string Backend::Impl::json_body(const Request& r, const rack::TypeDescription* type,
                                     std::vector<std::byte>& body) {
  return encode_command_body(r.body, type, body);
}

void Backend::Impl::class_command(uint64_t client, const Request& r) {
  const bool text_op = r.op == Op::kCommand;
  const std::string& wanted = text_op ? r.command_name : r.command;
  const BodyEncoder encode = text_op ? &Impl::text_fields_body : &Impl::json_body;
  const Address a = r.component;
  const auto ci = class_infos.find(a.raw() & 0xFFFF0000u);
  if (ci == class_infos.end() || !ci->second.desc) {
    (void)described(a);
    result(client, r, false,
           address_text(a) + ": command " + wanted +
               ": its class description is not known yet (asked; try again); nothing was sent");
    return;
  }
  const rack::ClassDescription& d = *ci->second.desc;
  const rack::CommandDescription* info = d.find_command(wanted);
  if (info == nullptr) {
    std::string names;
    for (const auto& c : d.commands) names += (names.empty() ? "" : ", ") + c.name;
    result(client, r, false,
           address_text(a) + ": class " + d.class_name + " has no command '" + wanted + "' (" +
               (names.empty() ? "it describes none" : "known: " + names) + "); nothing was sent");
    return;
  }
  auto body = std::make_shared<std::vector<std::byte>>();
  const rack::TypeDescription* type = info->body ? &*info->body : nullptr;
  const std::string why = encode(r, type, *body);
  if (!why.empty()) {
    {
      const std::lock_guard lock(counters_mutex);
      ++counters.malformed;
      ++counters.refused[static_cast<std::size_t>(Refusal::kBadValue)];
    }
    result(client, r, false, address_text(a) + ": " + info->name + ": " + why + "; nothing was sent");
    return;
  }
  // What was sent, for the dashboard's panel (a program knows what it sent: a
  // played-back scan's body is not echoed 25 times a second).
  std::string sent;
  if (text_op) sent = type != nullptr ? rack::payload_to_json(type->field_table(), *body, true) : "(no body)";
  const tims::ConstBuffer part{body->data(), body->size()};
  const std::string name = info->name;
  request(a, info->type,
          body->empty() ? std::span<const tims::ConstBuffer>() : std::span<const tims::ConstBuffer>(&part, 1),
          kOnTimeoutNs, [this, client, r, a, name, sent](const Reply* rep) {
            if (rep == nullptr || rep->header.type == msg::kError || rep->header.type == msg::kNotAvailable) {
              result(client, r, false, failure(rep, name, a));
              return;
            }
            std::string hex;
            for (std::size_t k = 0; k < rep->body.size() && k < 64; ++k) {
              static constexpr char kHex[] = "0123456789abcdef";
              const auto b = static_cast<unsigned>(rep->body[k]);
              hex += kHex[b >> 4];
              hex += kHex[b & 15u];
            }
            const bool ok = rep->header.type == msg::kOk;
            json m{{"type", "command_result"},
                   {"id", r.id ? json(*r.id) : json(nullptr)},
                   {"component", address_text(a)},
                   {"command", name},
                   {"sent", !sent.empty() && sent.front() == '{' ? json::parse(sent, nullptr, false) : json(nullptr)},
                   {"reply", ok ? "OK" : "type " + std::to_string(rep->header.type)},
                   {"reply_type", rep->header.type},
                   {"body_bytes", rep->body.size()},
                   {"body_hex", hex}};
            send_to(client, dump(m));
            result(client, r, true,
                   address_text(a) + ": " + name + (sent.empty() ? "" : " " + sent) + ": " +
                       (ok ? std::string("OK") : "reply " + std::to_string(rep->header.type)));
          });
}

std::string Backend::Impl::send_command(Address a, const std::string& name, const json& fields, ReplyHandler done) {
  const auto it = class_infos.find(a.raw() & 0xFFFF0000u);
  if (it == class_infos.end() || !it->second.desc) {
    (void)described(a);
    return address_text(a) + ": " + name + ": its class description is not known yet (asked; try again)";
  }
  const rack::ClassDescription& d = *it->second.desc;
  const rack::CommandDescription* c = d.find_command(name);
  if (c == nullptr) return address_text(a) + ": class " + d.class_name + " describes no command " + name;
  // The same encoder as "command_json" (json_body): nothing is sent unless every field fits.
  std::vector<std::byte> body;
  const std::string why = encode_command_body(fields, c->body ? &*c->body : nullptr, body);
  if (!why.empty()) return address_text(a) + ": " + name + ": " + why + " (not sent)";
  const tims::ConstBuffer part{body.data(), body.size()};
  // The body is copied into the mailbox by send(): a local is fine.
  request(a, c->type, std::span<const tims::ConstBuffer>(&part, body.empty() ? 0 : 1), default_timeout(),
          std::move(done));
  return "";
}

void Backend::Impl::all_off_step(uint64_t client, const Request& r, std::shared_ptr<std::vector<Address>> order,
                                 std::size_t i, std::shared_ptr<std::vector<std::string>> failures) {
  if (i >= order->size()) {
    const bool ok = failures->empty();
    std::string text = ok ? "robot " + std::to_string(r.system) + ": all " + std::to_string(order->size()) + " off"
                          : "";
    for (const auto& f : *failures) text += (text.empty() ? "" : "; ") + f;
    result(client, r, ok, text);
    poll_status();
    return;
  }
  const Address a = (*order)[i];
  request(a, msg::kOff, [this, client, r, order, i, failures, a](const Reply* rep) {
    if (rep == nullptr || rep->header.type != msg::kOk) failures->push_back(failure(rep, "OFF", a));
    all_off_step(client, r, order, i + 1, failures);
  });
}

void Backend::Impl::set_pose(uint64_t client, const Request& r) {
  const auto position = find(r.system, kPosition);
  const auto mcl = find(r.system, kMcl);
  if (!position && !mcl) {
    result(client, r, false, "robot " + std::to_string(r.system) + " has neither Position nor MCL");
    return;
  }
  const auto init_mcl = [this, client, r, mcl](std::string done) {
    if (!mcl) {
      result(client, r, true, done);
      return;
    }
    const Address a = *mcl;
    const json init{{"x", r.x}, {"y", r.y}, {"phi", r.phi}, {"sigma_xy", 0.3}, {"sigma_phi", 0.2}};
    const std::string why = send_command(a, "INIT", init, [this, client, r, a, done](const Reply* rep) {
      const bool ok = rep != nullptr && rep->header.type == msg::kOk;
      result(client, r, ok,
             ok ? done + (done.empty() ? "" : "; ") + address_text(a) + " re-initialised" : failure(rep, "INIT", a));
    });
    if (!why.empty()) result(client, r, false, done + (done.empty() ? "" : "; ") + why);
  };
  if (!position) {
    init_mcl("");
    return;
  }
  const int64_t t = robots[r.system].position_time_ns;
  if (t == 0) {
    result(client, r, false, address_text(*position) + ": no sample yet (is it on?): its time is needed for UPDATE");
    return;
  }
  // UPDATE refers to a time: the newest Position sample's, which the robot's
  // odometry certainly holds (this tool's clock need not be the robot's).
  const json update{{"time_ns", t},        {"x", r.x},           {"y", r.y},
                    {"phi", r.phi},        {"var_x", 0.3 * 0.3}, {"var_y", 0.3 * 0.3},
                    {"var_phi", 0.2 * 0.2}};
  const Address a = *position;
  const std::string why = send_command(a, "UPDATE", update, [this, client, r, a, init_mcl](const Reply* rep) {
    if (rep == nullptr || rep->header.type != msg::kOk) {
      result(client, r, false, failure(rep, "UPDATE", a));
      return;
    }
    init_mcl(address_text(a) + " updated");
  });
  if (!why.empty()) result(client, r, false, why);
}

void Backend::Impl::joystick(uint64_t client, const Request& r) {
  Robot& robot = robots[r.system];
  const auto chassis = find(r.system, kChassis);
  if (!chassis) {
    result(client, r, false, "robot " + std::to_string(r.system) + " has no Chassis");
    return;
  }
  if (robot.joystick_owner != 0 && robot.joystick_owner != client &&
      rt::monotonic_ns() - robot.joystick_last_ns < kDeadManNs) {
    result(client, r, false, "another browser drives robot " + std::to_string(r.system));
    return;
  }
  robot.joystick_owner = client;
  robot.joystick_last_ns = rt::monotonic_ns();
  robot.want_vx = r.vx;
  robot.want_omega = r.omega;
  robot.joystick_moving = r.vx != 0.0 || r.omega != 0.0;
  if (robot.claim_pending) return;  // the MOVE follows the claim
  if (!robot.claimed) {
    // Become the chassis' active pilot (the Pilot, if any, is preempted and stands).
    robot.claim_pending = true;
    const Address a = *chassis;
    const uint8_t s = r.system;
    const json claim{{"pilot", reply_mailbox.address().raw()}};
    const std::string why = send_command(a, "SET_ACTIVE_PILOT", claim, [this, client, r, a, s](const Reply* rep) {
      Robot& rb = robots[s];
      rb.claim_pending = false;
      if (rep == nullptr || rep->header.type != msg::kOk) {
        result(client, r, false, failure(rep, "SET_ACTIVE_PILOT", a));
        return;
      }
      rb.claimed = true;
      result(client, r, true, address_text(a) + ": the joystick is the active pilot");
      send_move(s, rb.want_vx, rb.want_omega);
    });
    if (!why.empty()) {
      robot.claim_pending = false;
      result(client, r, false, why);
    }
    return;
  }
  send_move(r.system, r.vx, r.omega);
}

void Backend::Impl::send_move(uint8_t system, double vx, double omega) {
  const auto chassis = find(system, kChassis);
  if (!chassis) return;
  const Address a = *chassis;
  const std::string why = send_command(
      a, "MOVE", json{{"vx", vx}, {"omega", omega}}, [this, system, a](const Reply* rep) {
        if (rep != nullptr && rep->header.type == msg::kOk) return;
        Robot& robot = robots[system];
        robot.claimed = false;  // taken over by another pilot: claim again on the next command
        if (robot.joystick_owner != 0) {
          send_to(robot.joystick_owner,
                  dump(json{{"type", "notice"}, {"level", "warning"}, {"text", failure(rep, "MOVE", a)}}));
        }
      });
  const Robot& robot = robots[system];
  if (!why.empty() && robot.joystick_owner != 0) {
    send_to(robot.joystick_owner, dump(json{{"type", "notice"}, {"level", "warning"}, {"text", why}}));
  }
}

void Backend::Impl::stop_joystick(uint8_t system) {
  Robot& robot = robots[system];
  if (robot.claimed || robot.claim_pending) send_move(system, 0.0, 0.0);
  robot.joystick_moving = false;
  robot.want_vx = robot.want_omega = 0.0;
  robot.joystick_owner = 0;
}

void Backend::Impl::release_joystick(uint8_t system) {
  Robot& robot = robots[system];
  robot.joystick_owner = 0;
  robot.joystick_moving = false;
  robot.claimed = false;
}

void Backend::Impl::check_dead_man() {
  const int64_t now = rt::monotonic_ns();
  for (auto& [s, robot] : robots) {
    if (robot.joystick_owner != 0 && now - robot.joystick_last_ns > kDeadManNs) {
      const uint64_t owner = robot.joystick_owner;
      const bool was_moving = robot.joystick_moving;
      stop_joystick(s);
      if (was_moving) {
        send_to(owner, dump(json{{"type", "notice"},
                                 {"level", "warning"},
                                 {"text", "joystick silent for 400 ms: robot " + std::to_string(s) + " stopped"}}));
      }
    }
  }
}

}  // namespace rack::gui
