#include "backend.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <utility>

#include "gdos_relay.h"
#include "report_watcher.h"
#include "rack/client/session.h"
#include "rack/core/class_description.h"
#include "rack/core/trace_session.h"
#include "rack/core/parameters.h"
#include "rack/core/payload_json.h"
#include "rack/core/wire.h"
#include "rack/interfaces/data_types.h"
#include "rack/interfaces/devices.h"
#include "rack/interfaces/navigation.h"
#include "rack/interfaces/robot.h"
#include "rack/maps/occupancy_map.h"
#include "rack/rt/clock.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/gdos_lcm.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/message.h"
#include "rack/tims/router.h"
#include "rack/tims/tool_address.h"
#include "field_names.h"  // tools/rackctl: enum and address names

namespace rack::gui {

namespace {

using nlohmann::json;
using tims::Address;
namespace msg = tims::msg;
namespace classes = tims::classes;
namespace ifc = rack::interfaces;
namespace rtrace = rack::trace;

constexpr uint32_t kSlotSize = 64 * 1024;  // the largest polled sample (Path) is ~17 KiB
constexpr uint32_t kReplySlots = 256;      // a poll round asks every component at once
// Camera images (0.9 MB): their replies go to a mailbox of their own with large slots.
constexpr uint32_t kImageSlotSize = static_cast<uint32_t>(sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) +
                                                          sizeof(rack::interfaces::CameraData));
constexpr uint32_t kImageSlots = 2;
constexpr int64_t kStaleNs = 1500 * rt::kNsPerMs;    // no status reply for this long: "no_reply"
constexpr int64_t kDeadManNs = 400 * rt::kNsPerMs;   // joystick silent this long: MOVE 0
constexpr int64_t kOnTimeoutNs = 6 * rt::kNsPerSec;  // ON is answered when on() has finished
constexpr int kMapRetryRounds = 50;                  // a map that failed to load: try again later
// Streams ("subscribe"): the samples of the subscribed components arrive in two
// mailboxes of their own, drained every worker pass (10 ms at most): small samples
// (chassis, odometry, position: 100 Hz each in sim_mcl) in 1024 slots of 4 KiB, the
// others (ladar, scan2d, MCL: 25 Hz) in 128 of 64 KiB; each holds a second or more of
// sim_mcl's streams while a pass is slow on a loaded machine. 12 MiB.
constexpr uint32_t kSmallStreamSlots = 1024;
constexpr uint32_t kSmallStreamSlotSize = 4096;
constexpr uint32_t kStreamSlots = 128;
constexpr int64_t kStreamRetryNs = rt::kNsPerSec;  // a refused subscription: asked again after this

std::string address_text(Address a) { return a.str(); }

std::string class_text(Address a) {
  const char* c = tims::class_name(a.class_id());
  if (c != nullptr) return c;
  char buf[16];
  std::snprintf(buf, sizeof buf, "Class0x%02x", a.class_id());
  return buf;
}

std::string base64(const std::vector<uint8_t>& in) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const uint32_t v = (uint32_t{in[i]} << 16) | (uint32_t{in[i + 1]} << 8) | in[i + 2];
    out += kAlphabet[(v >> 18) & 63u];
    out += kAlphabet[(v >> 12) & 63u];
    out += kAlphabet[(v >> 6) & 63u];
    out += kAlphabet[v & 63u];
  }
  if (i < in.size()) {
    uint32_t v = uint32_t{in[i]} << 16;
    if (i + 1 < in.size()) v |= uint32_t{in[i + 1]} << 8;
    out += kAlphabet[(v >> 18) & 63u];
    out += kAlphabet[(v >> 12) & 63u];
    out += i + 1 < in.size() ? kAlphabet[(v >> 6) & 63u] : '=';
    out += '=';
  }
  return out;
}

using rack::client::error_reason;  // the text of an ERROR body (rack/client/session.h)

std::string param_text(const char* s, std::size_t n) { return std::string(s, strnlen(s, n)); }

json param_json(const wire::ParamRecord& p) {
  json j = {{"name", param_text(p.name, sizeof p.name)},
            {"kind", rack::describe(static_cast<wire::ParamKind>(p.kind))},
            {"component_ref", (p.flags & 1u) != 0}};
  switch (static_cast<wire::ParamKind>(p.kind)) {
    case wire::ParamKind::kInt: j["value"] = p.int_value; break;
    case wire::ParamKind::kFloat:
      j["value"] = std::isfinite(p.float_value) ? json(p.float_value) : json(nullptr);
      break;
    case wire::ParamKind::kBool: j["value"] = p.int_value != 0; break;
    case wire::ParamKind::kString: j["value"] = param_text(p.string_value, sizeof p.string_value); break;
  }
  return j;
}

std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

// A class description as JSON, for tools that build on rack-gui's protocol (the
// Foxglove bridge, tools/foxglove, makes each class's JSON schema from it):
//   {"type":"class","system":0,"class_id":21,"class":"Chassis","impl":"ChassisSim",
//    "summary":..,"data":{"name":"ChassisData","size":120,"fields":[{"name":"vx",
//    "kind":"f64","count":1},..]} (null: no samples),"commands":[{"name":"MOVE",
//    "type":21,"summary":..,"body":{..} or null}],"parameters":[{"name":..,"kind":..,
//    "unit":..,"min":..,"max":..,"default":..,"doc":..,"choices":[..]}]}
// Field kinds: i8 u8 bool char i16 u16 i32 u32 i64 u64 f32 f64 (char arrays are strings).
json type_json(const rack::TypeDescription& t) {
  static constexpr const char* kKinds[] = {"i8",  "u8",  "bool", "char", "i16", "u16",
                                           "i32", "u32", "i64",  "u64",  "f32", "f64"};
  json fields = json::array();
  for (const auto& f : t.fields) {
    const auto k = static_cast<std::size_t>(f.kind);
    fields.push_back({{"name", f.name}, {"kind", k < std::size(kKinds) ? kKinds[k] : "u8"}, {"count", f.count}});
  }
  return {{"name", t.name}, {"size", t.size}, {"fields", std::move(fields)}};
}

std::string class_message(uint8_t system, const rack::ClassDescription& d,
                          std::optional<Address> component = std::nullopt) {
  json commands = json::array();
  for (const auto& c : d.commands) {
    commands.push_back({{"name", c.name},
                        {"type", c.type},
                        {"summary", c.summary},
                        {"body", c.body ? type_json(*c.body) : json(nullptr)}});
  }
  json params = json::array();
  for (const auto& p : d.parameters) {
    params.push_back({{"name", p.name},
                      {"kind", rack::describe(p.kind)},
                      {"unit", p.unit},
                      {"min", std::isfinite(p.min) ? json(p.min) : json(nullptr)},
                      {"max", std::isfinite(p.max) ? json(p.max) : json(nullptr)},
                      {"default", p.default_value},
                      {"doc", p.doc},
                      {"choices", p.choices}});
  }
  json m{{"type", "class"},
         {"system", system},
         {"class_id", d.class_id},
         {"class", d.class_name},
         {"impl", d.impl},
         {"summary", d.summary},
         {"data", d.data ? type_json(*d.data) : json(nullptr)},
         {"commands", std::move(commands)},
         {"parameters", std::move(params)}};
  if (component) m["component"] = address_text(component->component());
  return dump(m);
}

struct Reply {
  tims::MessageHeader header{};
  std::span<const std::byte> body;
  [[nodiscard]] bool native() const { return tims::body_is_native(header); }
};
// nullptr: no reply in time (or not sent).
using ReplyHandler = std::function<void(const Reply*)>;

struct Pending {
  Address dest;
  uint8_t seq = 0;
  int64_t deadline_ns = 0;
  ReplyHandler done;
};

struct Component {
  tims::ComponentInfo info;
  uint8_t system = 0;
  std::string host_key;   // host name + host id: the group it is shown in
  std::size_t order = 0;  // position in its host's announcement (host-file order)
  std::string state = "no_reply";
  int64_t last_reply_ns = 0;  // monotonic time of the last status reply
  bool status_pending = false;
  bool data_pending = false;
  bool stats_pending = false;
  json stats;  // the last GET_STATS, or null
  bool latency_pending = false;
  bool latency_refused = false;     // answered ERROR (a rackd from before GET_LATENCY): not asked again
  bool latency_bad_logged = false;  // a malformed reply was logged (once per component)
  json latency;                     // the last GET_LATENCY (gui_protocol.h: latency_json), or null
};

// What a class described of itself (GET_CLASS), per system and class id.
struct ClassInfo {
  std::optional<rack::ClassDescription> desc;
  std::vector<tims::FieldDesc> data_fields;  // desc->data's field table (names point into desc)
  rack::ClassPageAssembler pages;
  bool pending = false;  // a page request is out
  bool failed = false;   // refused or malformed: not asked again
};

// A component's data stream that clients subscribed to ("subscribe"): one
// GET_CONT_DATA subscription of the stream mailbox per component, shared by its
// clients, renewed every lease / 4 and taken up again after the producer dropped it
// (it left ENABLED, its host was lost) once the component is enabled again.
struct Stream {
  std::set<uint64_t> clients;
  int64_t period_ns = 0;    // asked for: 0 every sample (the shortest a client asked)
  bool active = false;      // the producer answered CONT_DATA and has not dropped it
  bool pending = false;     // a GET_CONT_DATA is out
  int64_t renew_at_ns = 0;  // the next renewal (0: none)
  int64_t retry_at_ns = 0;  // after a refusal: not asked again before this
  std::string why;          // why it is not streaming ("" when it is)
  uint32_t mailbox = 0;     // where its samples go (small or large slots), fixed while it is open
  std::vector<std::pair<uint64_t, Request>> waiting;  // subscribe requests answered by the next reply
};

struct Host {
  std::string name;
  uint8_t system = 0;
  uint8_t host_id = 0;
  int32_t pid = 0;
  bool alive = false;           // still announced by the network
  int64_t silent_since_ns = 0;  // monotonic time it stopped being announced (0: announced)
  std::string network;
};

struct Robot {
  // Joystick: who holds it and whether this tool is the chassis' active pilot.
  uint64_t joystick_owner = 0;
  int64_t joystick_last_ns = 0;
  bool joystick_moving = false;
  bool claimed = false;
  bool claim_pending = false;
  double want_vx = 0.0, want_omega = 0.0;
  int64_t position_time_ns = 0;  // host time of the newest Position sample
  // Map: loaded once (or from --map), retried while it fails.
  bool map_sent = false;
  bool map_pending = false;
  int map_retry = 0;
  std::string map_message;  // the map as a "map" message, for new clients
};

}  // namespace

struct Backend::Impl {
  Impl(BackendConfig c, Sink s)
      : config(std::move(c)),
        sink(std::move(s)),
        address_claim(tims::ToolAddressClaim::claim()),
        reply_mailbox(address_claim.mailbox(0), kReplySlots, kSlotSize),
        image_mailbox(address_claim.mailbox(1), kImageSlots, kImageSlotSize),
        stream_mailbox(address_claim.mailbox(2), kStreamSlots, kSlotSize),
        small_stream_mailbox(address_claim.mailbox(3), kSmallStreamSlots, kSmallStreamSlotSize),
        endpoint(router, reply_mailbox, kPriority),
        transport(router, transport_config(config)),
        buffer(kSlotSize),
        image_buffer(kImageSlotSize) {
    if (!address_claim.warning().empty()) std::fprintf(stderr, "rack-gui: %s\n", address_claim.warning().c_str());
    router.add(reply_mailbox);
    router.add(image_mailbox);
    router.add(stream_mailbox);
    router.add(small_stream_mailbox);
  }
  ~Impl() {
    stop();
    router.remove(reply_mailbox.address());
    router.remove(image_mailbox.address());
    router.remove(stream_mailbox.address());
    router.remove(small_stream_mailbox.address());
  }

  static constexpr uint8_t kPriority = 10;

  static tims::LcmTransportConfig transport_config(const BackendConfig& c) {
    tims::LcmTransportConfig t;
    t.url = c.lcm_url;
    tims::use_key_file(t, "rack-gui", c.key_file);  // as rackctl --key-file
    t.uplink_slots = 256;
    t.announce_period_ns = 0;  // a tool announces nothing
    t.role = tims::NodeRole::kTool;
    t.max_message_bytes = kImageSlotSize;  // camera images
    t.reassembly_slots = 4;
    t.large_slots = 2;
    t.warn = [](const std::string& s) { std::fprintf(stderr, "rack-gui: %s\n", s.c_str()); };
    return t;
  }

  void start() {
    transport.start();
    running = true;
    worker = std::thread([this] { run_worker(); });
    gdos.start();
    if (!config.reports_dir.empty()) reports.start();
  }
  void stop() {
    if (!running.exchange(false)) return;
    if (worker.joinable()) worker.join();
    gdos.stop();
    reports.stop();
    // The producers stop streaming now rather than when their lease runs out.
    for (const auto& [raw, st] : streams) {
      if (st.mailbox == 0) continue;
      wire::StopContDataRequest req;
      req.mailbox = st.mailbox;
      const tims::ConstBuffer part = tims::buffer_of(req);
      (void)endpoint.send(Address(raw), msg::kStopContData, std::span<const tims::ConstBuffer>(&part, 1));
    }
    transport.stop();
  }

  // ------------------------------------------------------------ output
  void send_to(uint64_t client, std::string m) { sink(client, std::move(m)); }
  void broadcast(std::string m) { sink(0, std::move(m)); }
  void result(uint64_t client, const Request& r, bool ok, const std::string& text) {
    send_to(client, result_message(r.id, r.op, ok, text));
  }

  // ------------------------------------------------------------ requests
  void request(Address dest, int8_t type, std::span<const tims::ConstBuffer> body, int64_t timeout_ns,
               ReplyHandler done, Address reply_to = Address()) {
    uint8_t seq = 0;
    const auto st = endpoint.send(dest, type, body, reply_to, &seq);
    {
      const std::lock_guard lock(counters_mutex);
      ++counters.requests;
    }
    if (!tims::delivered(st)) {
      done(nullptr);
      return;
    }
    // An older request to the same mailbox with the same sequence number (after 256
    // sends) would take this reply: it has long timed out, drop it.
    pending.erase(std::remove_if(pending.begin(), pending.end(),
                                 [&](const Pending& p) { return p.dest == dest && p.seq == seq; }),
                  pending.end());
    pending.push_back(Pending{dest, seq, rt::monotonic_ns() + timeout_ns, std::move(done)});
  }
  void request(Address dest, int8_t type, ReplyHandler done, int64_t timeout_ns = 0) {
    request(dest, type, {}, timeout_ns > 0 ? timeout_ns : default_timeout(), std::move(done));
  }
  template <typename T>
  void request(Address dest, int8_t type, const T& body, ReplyHandler done, int64_t timeout_ns = 0) {
    // The body is copied into the mailbox by send(): a local is fine.
    const tims::ConstBuffer part = tims::buffer_of(body);
    request(dest, type, std::span<const tims::ConstBuffer>(&part, 1), timeout_ns > 0 ? timeout_ns : default_timeout(),
            std::move(done));
  }
  [[nodiscard]] int64_t default_timeout() const { return int64_t{config.timeout_ms} * rt::kNsPerMs; }

  // Hands a received reply to the request it answers (by source and sequence number).
  void dispatch(const tims::Mailbox::Received& got, std::span<const std::byte> buf) {
    const Address from = got.header.source().component();
    const auto it = std::find_if(pending.begin(), pending.end(), [&](const Pending& p) {
      return p.dest.component() == from && p.seq == got.header.seq;
    });
    if (it == pending.end()) return;  // late: its request timed out
    ReplyHandler done = std::move(it->done);
    pending.erase(it);
    Reply r;
    r.header = got.header;
    r.body = buf.subspan(sizeof(tims::MessageHeader), got.length - sizeof(tims::MessageHeader));
    done(&r);
  }

  void receive_replies(int64_t wait_ns) {
    auto got = reply_mailbox.receive(buffer, wait_ns);
    while (got.status == tims::RecvStatus::kOk) {
      dispatch(got, buffer);
      got = reply_mailbox.receive(buffer, tims::Mailbox::kNonBlocking);
    }
    for (auto img = image_mailbox.receive(image_buffer, tims::Mailbox::kNonBlocking);
         img.status == tims::RecvStatus::kOk; img = image_mailbox.receive(image_buffer, tims::Mailbox::kNonBlocking)) {
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
    for (auto it = pending.begin(); it != pending.end();) {
      if (now >= it->deadline_ns) {
        expired.push_back(std::move(it->done));
        it = pending.erase(it);
      } else {
        ++it;
      }
    }
    if (!expired.empty()) {
      const std::lock_guard lock(counters_mutex);
      counters.timeouts += expired.size();
    }
    for (auto& done : expired) done(nullptr);
  }

  // Describes a failed or refused reply for the user.
  static std::string failure(const Reply* r, const std::string& what, Address dest) {
    if (r == nullptr) return address_text(dest) + ": no reply to " + what + " in time (host gone or busy?)";
    if (r->header.type == msg::kNotAvailable) return address_text(dest) + ": not available (no such component running)";
    if (r->header.type == msg::kError) return address_text(dest) + ": " + what + " refused: " + error_reason(r->body);
    return address_text(dest) + ": " + what + ": unexpected reply " + std::to_string(r->header.type);
  }

  // ------------------------------------------------------------ discovery and state
  void refresh_hosts() {
    forget_silent_hosts();
    for (auto& [key, h] : hosts) h.alive = false;
    for (const auto& h : transport.hosts()) {
      const std::string key = h.host + "#" + std::to_string(h.system) + "/" + std::to_string(h.host_id);
      Host& host = hosts[key];
      host.name = h.host;
      host.system = h.system;
      host.host_id = h.host_id;
      host.pid = h.pid;
      host.alive = true;
      host.silent_since_ns = 0;
      host.network = h.network;
      for (std::size_t i = 0; i < h.components.size(); ++i) {
        const auto& c = h.components[i];
        const uint32_t raw = c.address.component().raw();
        auto [it, fresh] = components.try_emplace(raw);
        Component& comp = it->second;
        if (fresh || comp.host_key != key) {
          // A component is shown on the host that announced it last (it moved, or
          // a router re-announced it before its executor did).
          if (!fresh && h.role != tims::NodeRole::kExecutor && hosts[comp.host_key].alive) continue;
          comp.host_key = key;
        }
        comp.info = c;
        comp.info.address = c.address.component();
        comp.system = c.address.system();
        comp.order = i;
      }
    }
  }

  // A host the network stopped announcing (it stopped, cleanly or not, and discovery
  // expired it) is shown as NOT ANSWERING for config.host_forget_ms, then leaves the
  // list with its components, and every browser is told so.
  void forget_silent_hosts() {
    const int64_t now = rt::monotonic_ns();
    std::vector<std::string> gone;
    for (auto& [key, h] : hosts) {
      if (h.alive) continue;
      if (h.silent_since_ns == 0) h.silent_since_ns = now;
      if (config.host_forget_ms >= 0 && now - h.silent_since_ns > int64_t{config.host_forget_ms} * rt::kNsPerMs) {
        gone.push_back(key);
      }
    }
    for (const auto& key : gone) {
      std::size_t removed = 0;
      for (auto it = components.begin(); it != components.end();) {
        if (it->second.host_key == key) {
          it = components.erase(it);
          ++removed;
        } else {
          ++it;
        }
      }
      const std::string text = "host " + hosts[key].name + " (" + key + ") silent for " +
                               std::to_string(config.host_forget_ms / 1000) + " s: removed from the list with its " +
                               std::to_string(removed) + " components";
      std::fprintf(stderr, "rack-gui: %s\n", text.c_str());
      broadcast(dump(json{{"type", "notice"}, {"level", "info"}, {"text", text}}));
      hosts.erase(key);
    }
  }

  [[nodiscard]] std::string shown_state(const Component& c, int64_t now) const {
    if (c.state == "not_available") return c.state;
    if (c.last_reply_ns == 0 || now - c.last_reply_ns > kStaleNs) return "no_reply";
    return c.state;
  }

  void poll_status() {
    for (auto& [raw, c] : components) {
      if (c.status_pending) continue;
      c.status_pending = true;
      const Address a(raw);
      request(a, msg::kGetStatus, [this, raw](const Reply* r) {
        auto it = components.find(raw);
        if (it == components.end()) return;
        Component& comp = it->second;
        comp.status_pending = false;
        if (r == nullptr) return;  // stays until kStaleNs passes: then "no_reply"
        switch (r->header.type) {
          case msg::kEnabled: comp.state = "enabled"; break;
          case msg::kDisabled: comp.state = "disabled"; break;
          case msg::kError: comp.state = "error"; break;
          case msg::kNotAvailable: comp.state = "not_available"; break;
          default: return;
        }
        comp.last_reply_ns = rt::monotonic_ns();
      });
    }
  }

  void poll_stats() {
    for (auto& [raw, c] : components) {
      if (c.stats_pending || shown_state(c, rt::monotonic_ns()) == "no_reply") continue;
      c.stats_pending = true;
      request(Address(raw), msg::kGetStats, [this, raw](const Reply* r) {
        auto it = components.find(raw);
        if (it == components.end()) return;
        it->second.stats_pending = false;
        wire::StatsReply st;
        if (r == nullptr || r->header.type != msg::kStats || !wire::read_payload(r->body, r->native(), st)) return;
        it->second.stats = {{"period_ns", st.period_ns},
                            {"data_task", st.data_task},
                            {"cycles", st.data.cycles},
                            {"overruns", st.data.overruns},
                            {"samples", st.data.samples},
                            {"latency_ns",
                             {{"min", st.data.latency_min_ns},
                              {"p50", st.data.latency_p50_ns},
                              {"p99", st.data.latency_p99_ns},
                              {"p999", st.data.latency_p999_ns},
                              {"max", st.data.latency_max_ns},
                              {"mean", st.data.latency_mean_ns}}},
                            {"published", st.published},
                            {"listeners", st.listeners},
                            {"commands", st.commands},
                            {"errors", st.errors},
                            {"malformed", st.malformed},
                            {"command_drops", st.command_drops}};
      });
    }
  }

  // The data task's latency histogram, with the stats: not for components whose stats
  // say they have no data task (their histogram is empty by definition).
  void poll_latency() {
    for (auto& [raw, c] : components) {
      if (c.latency_pending || c.latency_refused || shown_state(c, rt::monotonic_ns()) == "no_reply") continue;
      if (c.stats.is_object() && c.stats.value("data_task", 0) == 0) continue;
      c.latency_pending = true;
      request(Address(raw), msg::kGetLatency, [this, raw](const Reply* r) {
        auto it = components.find(raw);
        if (it == components.end()) return;
        it->second.latency_pending = false;
        if (r == nullptr) return;
        // A rackd from before GET_LATENCY answers ERROR (and counts it as malformed):
        // asking it again every second would only raise its count.
        if (r->header.type == msg::kError) it->second.latency_refused = true;
        if (r->header.type != msg::kLatency) return;
        wire::LatencyHistogram h;
        std::string why;
        if (!wire::read_payload(r->body, r->native(), h)) {
          why = "reply of " + std::to_string(r->body.size()) + " bytes, expected " + std::to_string(sizeof h);
        } else {
          auto j = latency_json(h);
          if (auto* ok = std::get_if<json>(&j)) {
            it->second.latency = std::move(*ok);
            return;
          }
          why = std::get<std::string>(j);
        }
        it->second.latency = nullptr;  // never a stale histogram beside new stats
        {
          const std::lock_guard lock(counters_mutex);
          ++counters.bad_replies;
        }
        if (!it->second.latency_bad_logged) {
          it->second.latency_bad_logged = true;
          std::fprintf(stderr, "rack-gui: %s: GET_LATENCY: malformed reply: %s (counted; logged once)\n",
                       address_text(Address(raw)).c_str(), why.c_str());
        }
      });
    }
  }

  // The description of a component's class (GET_CLASS: its pages one request at a
  // time, then decoded), per system and class id: every class's data view comes from
  // it, so a class rack-gui was not built with (a plug-in) shows its fields too.
  // nullptr until it is known; a component that refuses it is not asked again.
  const ClassInfo* described(Address a) {
    const uint32_t key = a.raw() & 0xFFFF0000u;
    ClassInfo& ci = class_infos[key];
    if (ci.desc) return &ci;
    if (ci.pending || ci.failed) return nullptr;
    ci.pending = true;
    rack::ClassPageRequest q;
    q.offset = ci.pages.next_offset();
    q.sections = rack::kClassSectionValueNames;  // enum and address names (the "names" object)
    request(a.component(), msg::kGetClass, q, [this, key, a](const Reply* r) {
      ClassInfo& info = class_infos[key];
      info.pending = false;
      if (r == nullptr) {  // asked again in a later round; a browser waiting is told now
        answer_class_waiters(key, a, nullptr, "no reply to GET_CLASS in time (host gone or busy?)");
        return;
      }
      std::string error;
      if (r->header.type != msg::kClass) {
        error = r->header.type == msg::kError ? "refused: " + error_reason(r->body)
                                              : "reply " + std::to_string(r->header.type);
      } else if (info.pages.add(r->body, r->native(), error) && !info.pages.complete()) {
        (void)described(a);  // the next page
        return;
      }
      rack::ClassDescription d;
      if (error.empty() && !rack::decode_class_description(info.pages.bytes(), d, error))
        error = "description: " + error;
      if (error.empty() && d.class_id != a.class_id()) error = "describes another class id";
      if (!error.empty()) {
        info.failed = true;
        answer_class_waiters(key, a, nullptr, "its class description could not be read: " + error);
        {
          const std::lock_guard lock(counters_mutex);
          ++counters.bad_replies;
        }
        std::fprintf(stderr, "rack-gui: %s: GET_CLASS: %s (its data is not shown)\n", address_text(a).c_str(),
                     error.c_str());
        return;
      }
      info.desc = std::move(d);
      if (info.desc->data) info.data_fields = info.desc->data->field_table();
      answer_class_waiters(key, a, &*info.desc, "");
      std::string message = class_message(a.system(), *info.desc);
      {
        const std::lock_guard lock(greet_mutex);
        class_messages[key] = message;
      }
      broadcast(std::move(message));
    });
    return nullptr;
  }

  void answer_class_waiters(uint32_t key, Address a, const rack::ClassDescription* d, const std::string& why) {
    const auto it = class_waiters.find(key);
    if (it == class_waiters.end()) return;
    auto waiting = std::move(it->second);
    class_waiters.erase(it);
    for (const auto& [client, r] : waiting) {
      if (d != nullptr) {
        send_to(client, class_message(r.component.system(), *d, r.component));
        result(client, r, true, address_text(r.component) + ": class " + d->class_name + " described");
      } else {
        result(client, r, false, address_text(a.component()) + ": " + why);
      }
    }
  }
  // Work for a later round of the worker (a trace that is still recording).
  void defer(int64_t delay_ns, std::function<void()> f) {
    deferred.emplace_back(rt::monotonic_ns() + delay_ns, std::move(f));
  }
  void run_deferred() {
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

  // A live task timeline of one host (as `rackctl trace --duration S all`): TRACE_START
  // to the executor's trace mailbox, TRACE_READ until the JSON is ready, read in
  // chunks, checked to be JSON, then sent to the browser that asked.
  void trace(uint64_t client, const Request& r) {
    const tims::HostInfo* host = nullptr;
    std::string names;
    const auto all = transport.hosts();
    for (const auto& h : all) {
      if (h.system != r.system || h.role != tims::NodeRole::kExecutor) continue;
      names += (names.empty() ? "" : ", ") + h.host;
      if (!r.host.empty() && h.host != r.host) continue;
      if (host != nullptr && r.host.empty()) {
        result(client, r, false,
               "robot " + std::to_string(r.system) + " has several hosts (" + names + "...): name one");
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
  void trace_read(uint64_t client, const Request& r, Address t, const std::string& host_name,
                  const std::shared_ptr<std::string>& text, int64_t give_up) {
    if (rt::monotonic_ns() > give_up) {
      result(client, r, false, host_name + ": the trace was not ready 30 s after its end");
      return;
    }
    rtrace::TraceReadRequest rr;
    rr.offset = text->size();
    request(t, rtrace::kTraceRead, rr, [this, client, r, t, host_name, text, give_up](const Reply* rep) {
      rtrace::TraceChunkHeader head;
      if (rep == nullptr || rep->header.type != msg::kOk || rep->body.size() < sizeof head) {
        result(client, r, false, failure(rep, "TRACE_READ", t));
        return;
      }
      std::memcpy(&head, rep->body.data(), sizeof head);
      const auto state = static_cast<rtrace::TraceState>(head.state);
      const auto again = [&](int64_t delay) {
        defer(delay,
              [this, client, r, t, host_name, text, give_up] { trace_read(client, r, t, host_name, text, give_up); });
      };
      if (state == rtrace::TraceState::kRecording) {
        again(std::clamp<int64_t>(head.remaining_ns, 10 * rt::kNsPerMs, 200 * rt::kNsPerMs));
        return;
      }
      if (state != rtrace::TraceState::kReady || head.length > rep->body.size() - sizeof head ||
          head.offset != text->size() || head.total > (100u << 20)) {
        result(client, r, false, host_name + ": TRACE_READ: the trace was discarded or its chunk is malformed");
        return;
      }
      text->append(reinterpret_cast<const char*>(rep->body.data() + sizeof head), head.length);
      if (text->size() < head.total) {
        if (head.length == 0) {
          result(client, r, false, host_name + ": TRACE_READ returned nothing before the end");
          return;
        }
        again(0);
        return;
      }
      const json doc = json::parse(*text, nullptr, false);
      if (doc.is_discarded()) {
        result(client, r, false, host_name + ": the trace is not JSON (" + std::to_string(text->size()) + " bytes)");
        return;
      }
      send_to(client, dump(json{{"type", "trace"},
                                {"host", host_name},
                                {"system", r.system},
                                {"dropped", head.dropped},
                                {"json", *text}}));
      result(client, r, true,
             host_name + ": trace of " + json(r.duration_s).dump() + " s, " + std::to_string(text->size()) + " bytes");
    });
  }

  // ------------------------------------------------------------ class commands
  // A class command by the name its class description gives it, for both ops:
  // "command" fills the body from text fields (as `rackctl send NAME CMD field=value`,
  // the dashboard's command panel), "command_json" from a typed JSON body (programs:
  // the Foxglove bridge's services, its player). One lookup of class and command, two
  // body encoders; nothing is sent unless every field fits. The client gets a
  // "command_result" (the reply's type and first bytes; the body sent, for "command")
  // and the result.
  //
  // An encoder fills `body` (the command's body type, `type` nullptr: none) and returns
  // the problem naming the field, or "".
  using BodyEncoder = std::string (*)(const Request& r, const rack::TypeDescription* type,
                                      std::vector<std::byte>& body);

  static std::string text_fields_body(const Request& r, const rack::TypeDescription* type,
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
  static std::string json_body(const Request& r, const rack::TypeDescription* type, std::vector<std::byte>& body) {
    return encode_command_body(r.body, type, body);
  }

  void class_command(uint64_t client, const Request& r) {
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

  // The name of a's class: TiMS' name, else its description's, else Class0xNN.
  // Addresses stay in TiMS' form (Class0x91(2/0) for a class TiMS does not name): the
  // dashboard sends them back in its requests, which gui_protocol parses without the
  // descriptions; "class" carries the described name beside them.
  std::string class_of(Address a) const {
    if (tims::class_name(a.class_id()) == nullptr) {
      const auto it = class_infos.find(a.raw() & 0xFFFF0000u);
      if (it != class_infos.end() && it->second.desc) return it->second.desc->class_name;
    }
    return class_text(a);
  }
  // Data the dashboard draws: the navigation classes every round, other classes with
  // a data type every `slow` rounds.
  void poll_data(uint64_t round) {
    const int64_t now = rt::monotonic_ns();
    for (auto& [raw, c] : components) {
      if (c.data_pending || shown_state(c, now) != "enabled") continue;
      const uint8_t cls = Address(raw).class_id();
      const ClassInfo* info = described(Address(raw));
      if (info == nullptr || !info->desc->data) continue;
      const bool fast = cls == classes::kChassis || cls == classes::kPosition || cls == classes::kMcl ||
                        cls == classes::kScan2d || cls == classes::kPilot || cls == classes::kLadar;
      if (cls == classes::kCamera) {
        if (round % 5 == 0) poll_image(raw);  // once a second: 0.9 MB each
        continue;
      }
      if (!fast && round % 5 != 0) continue;
      c.data_pending = true;
      wire::GetDataRequest req;
      request(Address(raw), msg::kGetData, req, [this, raw](const Reply* r) {
        auto it = components.find(raw);
        if (it == components.end()) return;
        Component& comp = it->second;
        comp.data_pending = false;
        if (r == nullptr || r->header.type != msg::kData) return;
        if (auto m = data_message(raw, comp, r->header, r->body, false)) broadcast(std::move(*m));
      });
    }
  }

  // A DATA message's sample (SampleHeader, then the class's data type) as a "data"
  // message for the browsers, decoded with the class description's field names;
  // nullopt when it does not decode (wrong size, class not described).
  std::optional<std::string> data_message(uint32_t raw, const Component& comp, const tims::MessageHeader& header,
                                          std::span<const std::byte> body, bool stream) {
    const auto ci = class_infos.find(raw & 0xFFFF0000u);
    if (ci == class_infos.end() || !ci->second.desc || !ci->second.desc->data) return std::nullopt;
    const ClassInfo& type = ci->second;
    const bool native = tims::body_is_native(header);
    wire::SampleHeader sh;
    if (body.size() < sizeof sh || !wire::read_payload(body.first(sizeof sh), native, sh)) return std::nullopt;
    const auto sample = body.subspan(sizeof sh);
    if (sample.size() != type.desc->data->size) return std::nullopt;
    const Address a(raw);
    if (a.class_id() == classes::kPosition) robots[comp.system].position_time_ns = sh.time_ns;
    if (a.class_id() == classes::kChassis) {
      ifc::ChassisData cd;
      if (wire::read_payload(sample, native, cd)) {
        robots[comp.system].claimed = cd.active_pilot == reply_mailbox.address().raw();
      }
    }
    json data = json::parse(rack::payload_to_json(type.data_fields, sample, native), nullptr, false);
    if (data.is_discarded()) return std::nullopt;
    trim_arrays(a.class_id(), data);
    // Enums and addresses by name beside the raw values (as rackctl get-data).
    json names = json::object();
    const std::string names_text = rack::tools::field_names_json(type.desc->value_names, type.data_fields, sample,
                                                                 native);
    if (!names_text.empty()) names = json::parse(names_text, nullptr, false);
    if (names.is_discarded()) names = json::object();
    json m{{"type", "data"},          {"component", address_text(a)}, {"name", comp.info.name},
           {"class", class_of(a)},    {"system", comp.system},        {"time_ns", sh.time_ns},
           {"sequence", sh.sequence}, {"data", std::move(data)},      {"names", std::move(names)}};
    if (stream) m["stream"] = true;
    return dump(m);
  }

  // A camera's newest image, as {"type":"image",...} with the pixels (or JPEG) in base64.
  void poll_image(uint32_t raw) {
    Component& c = components[raw];
    c.data_pending = true;
    wire::GetDataRequest req;
    const tims::ConstBuffer part = tims::buffer_of(req);
    request(
        Address(raw), msg::kGetData, std::span<const tims::ConstBuffer>(&part, 1), default_timeout(),
        [this, raw](const Reply* r) {
          auto it = components.find(raw);
          if (it == components.end()) return;
          Component& comp = it->second;
          comp.data_pending = false;
          wire::SampleHeader sh;
          auto img = std::make_unique<ifc::CameraData>();
          if (r == nullptr || r->header.type != msg::kData || r->body.size() != sizeof sh + sizeof *img ||
              !wire::read_payload(r->body.first(sizeof sh), r->native(), sh) ||
              !wire::read_payload(r->body.subspan(sizeof sh), r->native(), *img)) {
            return;
          }
          const std::size_t bytes = std::min<std::size_t>(img->bytes, sizeof img->data);
          const char* format = img->format == ifc::kCameraRgb8    ? "rgb"
                               : img->format == ifc::kCameraMono8 ? "mono"
                               : img->format == ifc::kCameraJpeg  ? "jpeg"
                                                                  : "unknown";
          broadcast(dump(json{{"type", "image"},
                              {"component", address_text(Address(raw))},
                              {"system", comp.system},
                              {"time_ns", sh.time_ns},
                              {"width", img->width},
                              {"height", img->height},
                              {"frame", img->frame},
                              {"dropped", img->dropped},
                              {"bad_frames", img->bad_frames},
                              {"format", format},
                              {"data", base64(std::vector<uint8_t>(img->data, img->data + bytes))}}));
        },
        image_mailbox.address());
  }

  // Fixed-capacity arrays are sent only up to their count (a scan of 541 beams, not
  // 1081 slots): a fifth of the bytes on a robot's Wi-Fi or SSH tunnel.
  static void trim_arrays(uint8_t cls, json& d) {
    const auto cut = [&d](const char* count, std::initializer_list<const char*> arrays) {
      if (!d.contains(count) || !d[count].is_number_unsigned()) return;
      const auto n = d[count].get<std::size_t>();
      for (const char* a : arrays) {
        if (d.contains(a) && d[a].is_array() && d[a].size() > n)
          d[a].erase(d[a].begin() + static_cast<std::ptrdiff_t>(n), d[a].end());
      }
    };
    switch (cls) {
      case classes::kLadar: cut("beam_count", {"range", "intensity"}); break;
      case classes::kScan2d: cut("point_count", {"x", "y", "range", "bearing", "type"}); break;
      case classes::kPath:
        cut("point_count", {"x", "y"});
        cut("waypoint_count", {"waypoint_x", "waypoint_y"});
        break;
      case classes::kMcl: cut("shown", {"particle_x", "particle_y", "particle_phi", "particle_weight"}); break;
      default: break;
    }
  }

  std::string components_message() const {
    const int64_t now = rt::monotonic_ns();
    std::map<uint8_t, std::map<std::string, std::vector<const Component*>>> by_robot;
    for (const auto& [raw, c] : components) by_robot[c.system][c.host_key].push_back(&c);
    json robots_j = json::array();
    for (auto& [system, by_host] : by_robot) {
      json hosts_j = json::array();
      for (auto& [key, list] : by_host) {
        std::sort(list.begin(), list.end(), [](const Component* a, const Component* b) { return a->order < b->order; });
        const auto h = hosts.find(key);
        json comps = json::array();
        for (const Component* c : list) {
          comps.push_back({{"address", address_text(c->info.address)},
                           {"name", c->info.name},
                           {"class", class_of(c->info.address)},
                           {"impl", c->info.impl},
                           {"state", shown_state(*c, now)},
                           {"stats", c->stats},
                           {"latency", c->latency}});
        }
        json hj = {{"key", key}, {"components", comps}};
        if (h != hosts.end()) {
          hj["host"] = h->second.name;
          hj["host_id"] = h->second.host_id;
          hj["pid"] = h->second.pid;
          hj["alive"] = h->second.alive;
          if (!h->second.alive && h->second.silent_since_ns != 0) {
            hj["silent_ms"] = (now - h->second.silent_since_ns) / rt::kNsPerMs;
            hj["forget_ms"] = config.host_forget_ms;
          }
          hj["network"] = h->second.network;
        }
        hosts_j.push_back(hj);
      }
      const auto r = robots.find(system);
      robots_j.push_back(
          {{"system", system}, {"hosts", hosts_j}, {"joystick", r != robots.end() && r->second.claimed}});
    }
    return dump(json{{"type", "components"}, {"robots", robots_j}});
  }

  // The first component of a class in a robot (lowest instance), preferring one that
  // answers.
  std::optional<Address> find(uint8_t system, uint8_t cls) const {
    std::optional<Address> best;
    bool best_alive = false;
    const int64_t now = rt::monotonic_ns();
    for (const auto& [raw, c] : components) {
      const Address a(raw);
      if (a.system() != system || a.class_id() != cls) continue;
      const bool alive = shown_state(c, now) == "enabled";
      if (!best || (alive && !best_alive)) {
        best = a;
        best_alive = alive;
      }
    }
    return best;
  }

  // ------------------------------------------------------------ maps
  void poll_maps() {
    std::set<uint8_t> systems;
    for (const auto& [raw, c] : components) systems.insert(c.system);
    for (const uint8_t s : systems) {
      Robot& robot = robots[s];
      if (robot.map_sent || robot.map_pending) continue;
      if (robot.map_retry > 0) {
        --robot.map_retry;
        continue;
      }
      if (const auto file = configured_map(s)) {
        load_and_send_map(s, *file, "--map");
        continue;
      }
      // The map the robot localises on: MCL's, else the simulators' `map` parameter.
      std::optional<Address> holder;
      for (const uint8_t cls : {classes::kMcl, classes::kLadar, classes::kChassis}) {
        if ((holder = find(s, cls))) break;
      }
      if (!holder) {
        robot.map_retry = kMapRetryRounds;
        continue;
      }
      robot.map_pending = true;
      wire::ParamName name;
      wire::copy_text(name.name, "map");
      const Address a = *holder;
      request(a, msg::kGetParam, name, [this, s, a](const Reply* r) {
        Robot& rb = robots[s];
        rb.map_pending = false;
        wire::ParamRecord p;
        if (r == nullptr || r->header.type != msg::kParam || !wire::read_payload(r->body, r->native(), p) ||
            static_cast<wire::ParamKind>(p.kind) != wire::ParamKind::kString) {
          rb.map_retry = kMapRetryRounds;  // no `map` parameter (a real robot): try the next time
          return;
        }
        const std::string file = param_text(p.string_value, sizeof p.string_value);
        if (file.empty()) {
          rb.map_retry = kMapRetryRounds;
          return;
        }
        load_and_send_map(s, file, address_text(a) + " parameter 'map'");
      });
    }
  }

  std::optional<std::string> configured_map(uint8_t system) const {
    std::optional<std::string> any;
    for (const auto& m : config.maps) {
      const auto eq = m.find('=');
      if (eq == std::string::npos) {
        any = m;
      } else if (m.substr(0, eq) == std::to_string(system)) {
        return m.substr(eq + 1);
      }
    }
    return any;
  }

  void load_and_send_map(uint8_t system, const std::string& file, const std::string& from) {
    Robot& robot = robots[system];
    std::filesystem::path path(file);
    if (path.is_relative()) path = std::filesystem::path(config.map_root) / path;
    const auto loaded = maps::load_map(path.string());
    if (!loaded.ok()) {
      robot.map_retry = kMapRetryRounds * 5;
      broadcast(
          dump(json{{"type", "notice"},
                    {"level", "error"},
                    {"text", "map of robot " + std::to_string(system) + " (" + from + "): " + loaded.error_text()}}));
      return;
    }
    const auto& m = *loaded.map;
    std::vector<uint8_t> cells(static_cast<std::size_t>(m.width()) * static_cast<std::size_t>(m.height()));
    for (int iy = 0; iy < m.height(); ++iy) {
      for (int ix = 0; ix < m.width(); ++ix) {
        cells[static_cast<std::size_t>(iy) * static_cast<std::size_t>(m.width()) +
              static_cast<std::size_t>(ix)] = static_cast<uint8_t>(m.cell_state(ix, iy));
      }
    }
    robot.map_message = dump(json{{"type", "map"},
                                  {"system", system},
                                  {"source", path.string()},
                                  {"width", m.width()},
                                  {"height", m.height()},
                                  {"resolution", m.resolution()},
                                  {"origin_x", m.origin_x()},
                                  {"origin_y", m.origin_y()},
                                  {"origin_yaw", m.origin_yaw()},
                                  {"cells", base64(cells)}});
    robot.map_sent = true;
    {
      const std::lock_guard lock(greet_mutex);
      map_messages[system] = robot.map_message;
    }
    broadcast(robot.map_message);
  }

  // ------------------------------------------------------------ client requests
  void handle(uint64_t client, const Request& r) {
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
          request(a, msg::kSetParam, p, [this, client, r, a, p](const Reply* rep2) {
            const bool ok = rep2 != nullptr && rep2->header.type == msg::kOk;
            result(client, r, ok,
                   ok ? address_text(a) + ": " + r.param_name + " = " + dump(param_json(p)["value"])
                      : failure(rep2, "SET_PARAM " + r.param_name, a));
          });
        });
        break;
      }
      case Op::kSetDestination: {
        const auto pilot = find(r.system, classes::kPilot);
        if (!pilot) {
          result(client, r, false, "robot " + std::to_string(r.system) + " has no Pilot");
          break;
        }
        ifc::PilotDestination d;
        d.x = r.x;
        d.y = r.y;
        const Address a = *pilot;
        request(a, ifc::kPilotSetDestination, d, [this, client, r, a](const Reply* rep) {
          const bool ok = rep != nullptr && rep->header.type == msg::kOk;
          if (ok) release_joystick(r.system);  // the Pilot takes the chassis back
          result(client, r, ok, ok ? address_text(a) + ": destination set" : failure(rep, "SET_DESTINATION", a));
        });
        break;
      }
      case Op::kFollowPath: {
        const auto pilot = find(r.system, classes::kPilot);
        if (!pilot) {
          result(client, r, false, "robot " + std::to_string(r.system) + " has no Pilot");
          break;
        }
        const Address a = *pilot;
        request(a, ifc::kPilotFollowPath, [this, client, r, a](const Reply* rep) {
          const bool ok = rep != nullptr && rep->header.type == msg::kOk;
          if (ok) release_joystick(r.system);
          result(client, r, ok, ok ? address_text(a) + ": following the path" : failure(rep, "FOLLOW_PATH", a));
        });
        break;
      }
      case Op::kGetClass: {
        const Address a = r.component;
        const ClassInfo* info = described(a);
        if (info != nullptr) {
          send_to(client, class_message(a.system(), *info->desc, a));
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

  // ------------------------------------------------------------ streams
  // "subscribe": the client is added to the component's stream (opened when it is
  // the first); answered when the producer answers (or at once when it streams already
  // at the period asked for).
  void subscribe(uint64_t client, const Request& r) {
    const uint32_t raw = r.component.raw();
    const auto [it, fresh] = streams.try_emplace(raw);
    Stream& s = it->second;
    const auto period = static_cast<int64_t>(std::llround(r.period_ms * 1e6));
    const int64_t before = s.period_ns;
    s.period_ns = fresh || s.clients.empty() ? period : std::min(s.period_ns, period);
    s.clients.insert(client);
    if (s.active && s.period_ns == before) {
      result(client, r, true, address_text(r.component) + ": streaming");
      return;
    }
    s.waiting.emplace_back(client, r);
    s.retry_at_ns = 0;
    open_stream(raw);
  }

  // GET_CONT_DATA into the stream mailbox: a new subscription, a renewal of its lease
  // or a new period (the producer keeps one listener per mailbox).
  void open_stream(uint32_t raw) {
    Stream& s = streams[raw];
    if (s.pending) return;
    s.pending = true;
    if (s.mailbox == 0) {
      // Small samples to the mailbox of small slots; an undescribed class to the large.
      const auto ci = class_infos.find(raw & 0xFFFF0000u);
      const bool small = ci != class_infos.end() && ci->second.desc && ci->second.desc->data &&
                         sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + ci->second.desc->data->size <=
                             kSmallStreamSlotSize;
      s.mailbox = (small ? small_stream_mailbox : stream_mailbox).address().raw();
    }
    wire::ContDataRequest req;
    req.period_ns = s.period_ns;
    req.mailbox = s.mailbox;
    const Address a(raw);
    request(a, msg::kGetContData, req, [this, raw, a, req](const Reply* rep) {
      const auto it = streams.find(raw);
      wire::ContDataReply cd;
      const bool ok = rep != nullptr && rep->header.type == msg::kContData &&
                      wire::read_payload(rep->body, rep->native(), cd);
      if (it == streams.end()) {  // every client left meanwhile: stop it
        if (ok) {
          wire::StopContDataRequest stop;
          stop.mailbox = req.mailbox;
          request(a, msg::kStopContData, stop, [](const Reply*) {});
        }
        return;
      }
      Stream& st = it->second;
      st.pending = false;
      const int64_t now = rt::monotonic_ns();
      std::string text;
      if (ok) {
        st.active = true;
        st.why.clear();
        st.renew_at_ns = cd.lease_ns > 0 ? now + cd.lease_ns / 4 : 0;
        text = address_text(a) + ": streaming " +
               (cd.period_ns > 0 && st.period_ns > 0
                    ? "a sample every " + json(static_cast<double>(cd.period_ns) / 1e6).dump() + " ms"
                    : std::string("every sample"));
      } else {
        st.active = false;
        st.renew_at_ns = 0;
        st.retry_at_ns = now + kStreamRetryNs;
        st.why = failure(rep, "GET_CONT_DATA", a);
        text = st.why + "; still subscribed: it streams once the component is enabled";
      }
      for (const auto& [client, asked] : std::exchange(st.waiting, {})) result(client, asked, ok, text);
    });
  }

  void stop_stream(uint32_t raw) {
    const auto it = streams.find(raw);
    if (it == streams.end()) return;
    if (it->second.mailbox != 0) {
      wire::StopContDataRequest req;
      req.mailbox = it->second.mailbox;
      request(Address(raw), msg::kStopContData, req, [](const Reply*) {});  // best effort: it may be gone
    }
    streams.erase(it);
  }

  // Every poll round: renew the leases, take up streams the producers dropped.
  void maintain_streams() {
    const int64_t now = rt::monotonic_ns();
    for (auto& [raw, s] : streams) {
      if (s.pending) continue;
      const auto c = components.find(raw);
      const std::string state = c == components.end() ? "gone" : shown_state(c->second, now);
      if (s.active) {
        if (state != "enabled" && state != "no_reply") s.active = false;  // it went off: the ERROR may be lost
        else if (s.renew_at_ns != 0 && now >= s.renew_at_ns) open_stream(raw);
        continue;
      }
      if (state != "enabled" || now < s.retry_at_ns) continue;
      const ClassInfo* info = described(Address(raw));
      if (info == nullptr) continue;  // asked; the next round
      const std::size_t bytes = info->desc->data
                                    ? sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + info->desc->data->size
                                    : 0;
      if (bytes == 0 || bytes > kSlotSize) {
        s.retry_at_ns = INT64_MAX;  // not streamed: no data, or a sample larger than a slot (camera images)
        s.why = address_text(Address(raw)) + ": class " + info->desc->class_name +
                (bytes == 0 ? std::string(" publishes no data")
                            : " samples of " + std::to_string(bytes) + " bytes are larger than a stream slot (" +
                                  std::to_string(kSlotSize) + "): only polled");
        for (const auto& [client, req] : std::exchange(s.waiting, {})) result(client, req, false, s.why);
        continue;
      }
      open_stream(raw);
    }
  }

  // A message of the stream mailbox: a sample goes to the stream's clients; an ERROR
  // (the producer left ENABLED, its host was lost) or the end of a replay's stream
  // ends the subscription until maintain_streams() takes it up again.
  void stream_sample(const tims::Mailbox::Received& got, std::span<const std::byte> buf) {
    const uint32_t raw = got.header.source().component().raw();
    const auto it = streams.find(raw);
    if (it == streams.end()) return;  // unsubscribed: its STOP_CONT_DATA is on the way
    Stream& s = it->second;
    const auto body = buf.subspan(sizeof(tims::MessageHeader), got.length - sizeof(tims::MessageHeader));
    if (got.header.type == msg::kError || got.header.type == msg::kEndOfStream) {
      s.active = false;
      s.renew_at_ns = 0;
      s.retry_at_ns = rt::monotonic_ns() + kStreamRetryNs;
      s.why = address_text(Address(raw)) +
              (got.header.type == msg::kError ? ": stream ended: " + error_reason(body) : ": end of stream");
      return;
    }
    if (got.header.type != msg::kData) return;
    const auto c = components.find(raw);
    if (c == components.end()) return;
    auto m = data_message(raw, c->second, got.header, body, true);
    if (!m) {
      const std::lock_guard lock(counters_mutex);
      ++counters.bad_replies;
      return;
    }
    {
      const std::lock_guard lock(counters_mutex);
      ++counters.streamed;
    }
    for (const uint64_t client : s.clients) send_to(client, *m);
  }

  void all_off_step(uint64_t client, const Request& r, std::shared_ptr<std::vector<Address>> order, std::size_t i,
                    std::shared_ptr<std::vector<std::string>> failures) {
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

  void set_pose(uint64_t client, const Request& r) {
    const auto position = find(r.system, classes::kPosition);
    const auto mcl = find(r.system, classes::kMcl);
    if (!position && !mcl) {
      result(client, r, false, "robot " + std::to_string(r.system) + " has neither Position nor MCL");
      return;
    }
    const auto init_mcl = [this, client, r, mcl](std::string done) {
      if (!mcl) {
        result(client, r, true, done);
        return;
      }
      ifc::MclInit init;
      init.x = r.x;
      init.y = r.y;
      init.phi = r.phi;
      init.sigma_xy = 0.3;
      init.sigma_phi = 0.2;
      const Address a = *mcl;
      request(a, ifc::kMclInit, init, [this, client, r, a, done](const Reply* rep) {
        const bool ok = rep != nullptr && rep->header.type == msg::kOk;
        result(client, r, ok,
               ok ? done + (done.empty() ? "" : "; ") + address_text(a) + " re-initialised" : failure(rep, "INIT", a));
      });
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
    ifc::PositionUpdate u;
    u.time_ns = t;
    u.x = r.x;
    u.y = r.y;
    u.phi = r.phi;
    u.var_x = u.var_y = 0.3 * 0.3;
    u.var_phi = 0.2 * 0.2;
    const Address a = *position;
    request(a, ifc::kPositionUpdate, u, [this, client, r, a, init_mcl](const Reply* rep) {
      if (rep == nullptr || rep->header.type != msg::kOk) {
        result(client, r, false, failure(rep, "UPDATE", a));
        return;
      }
      init_mcl(address_text(a) + " updated");
    });
  }

  void joystick(uint64_t client, const Request& r) {
    Robot& robot = robots[r.system];
    const auto chassis = find(r.system, classes::kChassis);
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
      ifc::ChassisSetActivePilot claim;
      claim.pilot = reply_mailbox.address().raw();
      const Address a = *chassis;
      const uint8_t s = r.system;
      request(a, ifc::kChassisSetActivePilot, claim, [this, client, r, a, s](const Reply* rep) {
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
      return;
    }
    send_move(r.system, r.vx, r.omega);
  }

  void send_move(uint8_t system, double vx, double omega) {
    const auto chassis = find(system, classes::kChassis);
    if (!chassis) return;
    ifc::ChassisMove m;
    m.vx = vx;
    m.omega = omega;
    const Address a = *chassis;
    request(a, ifc::kChassisMove, m, [this, system, a](const Reply* rep) {
      if (rep != nullptr && rep->header.type == msg::kOk) return;
      Robot& robot = robots[system];
      robot.claimed = false;  // taken over by another pilot: claim again on the next command
      if (robot.joystick_owner != 0) {
        send_to(robot.joystick_owner,
                dump(json{{"type", "notice"}, {"level", "warning"}, {"text", failure(rep, "MOVE", a)}}));
      }
    });
  }

  void stop_joystick(uint8_t system) {
    Robot& robot = robots[system];
    if (robot.claimed || robot.claim_pending) send_move(system, 0.0, 0.0);
    robot.joystick_moving = false;
    robot.want_vx = robot.want_omega = 0.0;
    robot.joystick_owner = 0;
  }
  void release_joystick(uint8_t system) {
    Robot& robot = robots[system];
    robot.joystick_owner = 0;
    robot.joystick_moving = false;
    robot.claimed = false;
  }

  // Dead-man: the browser sends joystick commands ten times a second while the stick
  // is held; silence (a frozen tab, a lost network) stops the robot. The chassis
  // watchdog stops it as well should this tool die.
  void check_dead_man() {
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

  // ------------------------------------------------------------ threads
  void run_worker() {
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
      for (auto& [client, req] : work) handle(client, req);
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

  void greet(uint64_t client) {
    send_to(client, dump(json{{"type", "hello"}, {"version", 1}, {"lcm", config.lcm_url}}));
    const std::lock_guard lock(greet_mutex);
    if (!last_components.empty()) send_to(client, last_components);
    for (const auto& [k, m] : class_messages) send_to(client, m);
    for (const auto& [s, m] : map_messages) send_to(client, m);
    if (std::string g = gdos.snapshot(); !g.empty()) send_to(client, std::move(g));
    if (std::string r = reports.snapshot(); !r.empty()) send_to(client, std::move(r));
  }

  BackendConfig config;
  Sink sink;
  tims::Router router{tims::kToolSystem};
  // rack-gui's mailbox addresses (0 replies, 1 images), held by no other tool while it
  // runs (rack/tims/tool_address.h).
  tims::ToolAddressClaim address_claim;
  tims::Mailbox reply_mailbox;
  tims::Mailbox image_mailbox;
  tims::Mailbox stream_mailbox;        // the samples of subscribed streams (mailbox 2)
  tims::Mailbox small_stream_mailbox;  // their small samples (mailbox 3)
  tims::Endpoint endpoint;
  tims::LcmTransport transport;
  std::vector<std::byte> buffer;
  std::vector<std::byte> image_buffer;
  std::atomic<bool> running{false};
  std::thread worker;
  // Every host's log, on a thread of its own (gdos_relay.h). A keyed network's log is
  // signed: the same key file verifies it.
  GdosRelay gdos{config.gdos_url.empty() ? config.lcm_url : config.gdos_url,
                 config.gdos_channel.empty() ? std::string(tims::kGdosChannel) : config.gdos_channel,
                 config.gdos_url.empty() || config.gdos_url == config.lcm_url ? config.key_file : std::string(),
                 [this](std::string m) { broadcast(std::move(m)); }};
  // The report files, symbolized on a thread of its own (report_watcher.h).
  ReportWatcher reports{config.reports_dir, config.backtrace_path, [this](std::string m) { broadcast(std::move(m)); }};

  // Worker thread only.
  std::vector<Pending> pending;
  std::map<uint32_t, Component> components;
  std::map<uint32_t, ClassInfo> class_infos;  // system << 24 | class id << 16 (described())
  std::map<uint32_t, std::vector<std::pair<uint64_t, Request>>> class_waiters;
  std::vector<std::pair<int64_t, std::function<void()>>>
      deferred;  // worker thread only (defer())  // get_class before it is known
  std::map<std::string, Host> hosts;
  std::map<uint8_t, Robot> robots;
  std::map<uint32_t, Stream> streams;  // by component address ("subscribe")

  std::mutex queue_mutex;  // server thread -> worker
  std::deque<std::pair<uint64_t, Request>> queue;
  std::vector<uint64_t> closed_clients;

  std::mutex greet_mutex;  // worker thread -> server thread (new clients)
  std::string last_components;
  std::map<uint8_t, std::string> map_messages;
  std::map<uint32_t, std::string> class_messages;  // "class" messages by system and class id

  mutable std::mutex counters_mutex;
  Counters counters;
  int64_t last_refusal_log_ns = 0;  // under counters_mutex
  uint64_t refusals_not_logged = 0;

  // Counts a refused client message by reason, answers it with the reason, and logs
  // it on stderr at most once a second (with how many were not logged since).
  void refuse(uint64_t client, const ParseError& e) {
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
};

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
