#include "backend.h"

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string_view>

#include "gdos_view.h"
#include "rack/client/session.h"
#include "rack/core/class_description.h"
#include "rack/core/parameters.h"
#include "rack/core/trace_session.h"
#include "rack/core/payload_json.h"
#include "rack/core/wire.h"
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
namespace rtrace = rack::trace;

constexpr uint32_t kSlotSize = 64 * 1024;  // the largest polled sample (Path) is ~17 KiB
constexpr uint32_t kReplySlots = 256;      // a poll round asks every component at once
// Camera images (0.9 MB): their replies go to a mailbox of their own with large slots.
// rack-gui links no class: the image's size is its class description's (a camera
// whose samples do not fit is shown without its image, and says so once).
constexpr uint32_t kImageSlotSize = 2 * 1024 * 1024;
constexpr uint32_t kImageSlots = 2;
constexpr int64_t kStaleNs = 1500 * rt::kNsPerMs;    // no status reply for this long: "no_reply"
constexpr int64_t kDeadManNs = 400 * rt::kNsPerMs;   // joystick silent this long: MOVE 0
constexpr int64_t kOnTimeoutNs = 6 * rt::kNsPerSec;  // ON is answered when on() has finished
constexpr std::size_t kRecentLog = 500;              // GDOS records kept for new clients
constexpr int kMapRetryRounds = 50;                  // a map that failed to load: try again later

std::string class_text(Address a) {
  const char* c = tims::class_name(a.class_id());
  if (c != nullptr) return c;
  char buf[16];
  std::snprintf(buf, sizeof buf, "Class0x%02x", a.class_id());
  return buf;
}

// Class names of the panels: rack-gui links no class and finds the components it
// drives (the joystick's chassis, the pilot of a destination, ...) by the class name
// their descriptions give, and sends their commands by name through those
// descriptions (Impl::send_command).
constexpr const char* kChassis = "Chassis";
constexpr const char* kPilot = "Pilot";
constexpr const char* kPosition = "Position";
constexpr const char* kMcl = "MCL";
constexpr const char* kLadar = "Ladar";
constexpr const char* kCamera = "Camera";

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

// `component`: the address text of the component asked about (a reply to get_class).
std::string class_message(uint8_t system, const rack::ClassDescription& d,
                          const std::optional<std::string>& component = std::nullopt) {
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
  if (component) m["component"] = *component;
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
        endpoint(router, reply_mailbox, kPriority),
        transport(router, transport_config(config)),
        buffer(kSlotSize),
        image_buffer(kImageSlotSize) {
    if (!address_claim.warning().empty()) std::fprintf(stderr, "rack-gui: %s\n", address_claim.warning().c_str());
    router.add(reply_mailbox);
    router.add(image_mailbox);
  }
  ~Impl() {
    stop();
    router.remove(reply_mailbox.address());
    router.remove(image_mailbox.address());
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
    gdos_thread = std::thread([this] { run_gdos(); });
    if (!config.reports_dir.empty()) reports_thread = std::thread([this] { run_reports(); });
  }
  void stop() {
    if (!running.exchange(false)) return;
    if (worker.joinable()) worker.join();
    if (gdos_thread.joinable()) gdos_thread.join();
    if (reports_thread.joinable()) reports_thread.join();
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
  std::string failure(const Reply* r, const std::string& what, Address dest) const {
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
        // Its class by name (the list, addresses, the panels' components) as soon as
        // it answers: rack-gui links no class.
        if (comp.state != "not_available") (void)described(Address(raw));
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
        class_names[key] = info.desc->class_name;
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
        send_to(client, class_message(r.component.system(), *d, address_text(r.component)));
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

  // A class command by name, its body filled from the browser's fields through the
  // class's own description (as `rackctl send NAME CMD field=value`).
  void command(uint64_t client, const Request& r) {
    const Address a = r.component;
    const auto ci = class_infos.find(a.raw() & 0xFFFF0000u);
    if (ci == class_infos.end() || !ci->second.desc) {
      (void)described(a);
      result(client, r, false,
             address_text(a) + ": command " + r.command_name +
                 ": its class description is not known yet (asked; try again)");
      return;
    }
    const rack::ClassDescription& d = *ci->second.desc;
    const rack::CommandDescription* info = d.find_command(r.command_name);
    if (info == nullptr) {
      std::string names;
      for (const auto& c : d.commands) names += (names.empty() ? "" : ", ") + c.name;
      result(client, r, false,
             address_text(a) + ": class " + d.class_name + " has no command '" + r.command_name + "' (" +
                 (names.empty() ? "it describes none" : "known: " + names) + "); nothing was sent");
      return;
    }
    auto body = std::make_shared<std::vector<std::byte>>();
    std::string sent = "(no body)";
    if (info->body) {
      const std::vector<tims::FieldDesc> table = info->body->field_table();
      body->assign(info->body->size, std::byte{0});
      for (const auto& [key, text] : r.fields) {
        const tims::FieldDesc* field = nullptr;
        for (const auto& f : table) {
          if (key == f.name) field = &f;
        }
        const std::string why = field == nullptr ? "no such field in " + info->body->name
                                                 : rack::set_field_from_text(*field, *body, text);
        if (!why.empty()) {
          {
            const std::lock_guard lock(counters_mutex);
            ++counters.malformed;
            ++counters.refused[static_cast<std::size_t>(Refusal::kBadValue)];
          }
          result(client, r, false,
                 address_text(a) + ": " + info->name + " field '" + key + "': " + why + "; nothing was sent");
          return;
        }
      }
      sent = rack::payload_to_json(table, *body, true);
    } else if (!r.fields.empty()) {
      result(client, r, false, address_text(a) + ": " + info->name + " takes no fields; nothing was sent");
      return;
    }
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
              send_to(client,
                      dump(json{{"type", "command_result"},
                                {"id", r.id ? json(*r.id) : json(nullptr)},
                                {"component", address_text(a)},
                                {"command", name},
                                {"sent", sent.front() == '{' ? json::parse(sent, nullptr, false) : json(nullptr)},
                                {"reply", ok ? "OK" : "type " + std::to_string(rep->header.type)},
                                {"reply_type", rep->header.type},
                                {"body_bytes", rep->body.size()},
                                {"body_hex", hex}}));
              result(client, r, true,
                     address_text(a) + ": " + name + " " + sent + ": " +
                         (ok ? std::string("OK") : "reply " + std::to_string(rep->header.type)));
            });
  }

  // The name of a's class: TiMS' name (the executor's, tools'), else its
  // description's, else Class0xNN (not described yet).
  std::string class_of(Address a) const {
    if (tims::class_name(a.class_id()) == nullptr) {
      const auto it = class_infos.find(a.raw() & 0xFFFF0000u);
      if (it != class_infos.end() && it->second.desc) return it->second.desc->class_name;
    }
    return class_text(a);
  }
  // An address as the page shows it and sends it back: its class by name (Counter(2/0),
  // a plug-in's as a built-in's); resolve_component() reads it.
  std::string address_text(Address a) const { return rack::client::address_text(a, class_of(a)); }

  // A request's component given by a class name TiMS does not know (every component
  // class: rack-gui links none), as the page sends it: the component at that system
  // and instance whose class describes itself with that name (or implementation
  // name). False, with the client answered, when none is known (yet).
  bool resolve_component(uint64_t client, Request& r) {
    if (r.component_class.empty()) return true;
    for (const auto& [raw, c] : components) {
      const Address a(raw);
      if (a.system() != r.component.system() || a.instance() != r.component.instance()) continue;
      if (class_of(a) == r.component_class || c.info.impl == r.component_class) {
        r.component = a;
        r.component_class.clear();
        return true;
      }
    }
    result(client, r, false,
           r.component_class + "(" + std::to_string(r.component.system()) + "/" +
               std::to_string(r.component.instance()) +
               "): no component of that class is known at that system and instance (yet: its class is described "
               "when it first answers)");
    return false;
  }
  // Data the dashboard draws: the navigation classes every round, other classes with
  // a data type every `slow` rounds.
  void poll_data(uint64_t round) {
    const int64_t now = rt::monotonic_ns();
    for (auto& [raw, c] : components) {
      if (c.data_pending || shown_state(c, now) != "enabled") continue;
      const ClassInfo* info = described(Address(raw));
      if (info == nullptr || !info->desc->data) continue;
      const uint32_t class_key = raw & 0xFFFF0000u;
      const std::string& cls = info->desc->class_name;
      const bool fast = cls == kChassis || cls == kPosition || cls == kMcl || cls == "Scan2D" || cls == kPilot ||
                        cls == kLadar;
      if (cls == kCamera) {
        if (round % 5 == 0) poll_image(raw);  // once a second: 0.9 MB each
        continue;
      }
      if (!fast && round % 5 != 0) continue;
      c.data_pending = true;
      wire::GetDataRequest req;
      request(Address(raw), msg::kGetData, req, [this, raw, class_key](const Reply* r) {
        auto it = components.find(raw);
        if (it == components.end()) return;
        Component& comp = it->second;
        comp.data_pending = false;
        const ClassInfo& type = class_infos[class_key];
        wire::SampleHeader sh;
        if (r == nullptr || r->header.type != msg::kData || r->body.size() < sizeof sh ||
            !wire::read_payload(r->body.first(sizeof sh), r->native(), sh)) {
          return;
        }
        const auto sample = r->body.subspan(sizeof sh);
        if (sample.size() != type.desc->data->size) return;
        const Address a(raw);
        const std::string& sample_class = type.desc->class_name;
        json data = json::parse(rack::payload_to_json(type.data_fields, sample, r->native()), nullptr, false);
        if (data.is_discarded()) return;
        if (sample_class == kPosition) robots[comp.system].position_time_ns = sh.time_ns;
        // Whether the joystick is the chassis' active pilot (a field of its data).
        if (sample_class == kChassis && data.contains("active_pilot") && data["active_pilot"].is_number_unsigned()) {
          robots[comp.system].claimed = data["active_pilot"].get<uint64_t>() == reply_mailbox.address().raw();
        }
        trim_arrays(sample_class, data);
        // Enums and addresses by name beside the raw values (as rackctl get-data);
        // an address by the name its class describes (Pilot(0/0)).
        json names = json::object();
        const std::string names_text = rack::tools::field_names_json(
            type.desc->value_names, type.data_fields, sample, r->native(), [this](Address named) {
              (void)described(named);  // its class name for the next sample, when not known yet
              return address_text(named);
            });
        if (!names_text.empty()) names = json::parse(names_text, nullptr, false);
        if (names.is_discarded()) names = json::object();
        broadcast(dump(json{{"type", "data"},
                            {"component", address_text(a)},
                            {"name", comp.info.name},
                            {"class", class_of(a)},
                            {"system", comp.system},
                            {"time_ns", sh.time_ns},
                            {"sequence", sh.sequence},
                            {"data", std::move(data)},
                            {"names", std::move(names)}}));
      });
    }
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
          // The image's fields by name through the camera class's description
          // (CameraData: width, height, bytes used of `data`, format by its value name).
          const auto ci = class_infos.find(raw & 0xFFFF0000u);
          wire::SampleHeader sh;
          if (r == nullptr || r->header.type != msg::kData || ci == class_infos.end() || !ci->second.desc ||
              !ci->second.desc->data || r->body.size() != sizeof sh + ci->second.desc->data->size ||
              !wire::read_payload(r->body.first(sizeof sh), r->native(), sh)) {
            return;
          }
          const auto sample = r->body.subspan(sizeof sh);
          const auto& fields = ci->second.data_fields;
          const auto number = [&](const char* name) -> uint64_t {
            const tims::FieldDesc* f = rack::tools::find_field(fields, name);
            return f != nullptr ? rack::tools::unsigned_field(*f, sample, r->native()).value_or(0) : 0;
          };
          const tims::FieldDesc* pixels = rack::tools::find_field(fields, "data");
          if (pixels == nullptr || pixels->kind != tims::FieldKind::kU8 || pixels->offset > sample.size() ||
              sample.size() - pixels->offset < pixels->count) {
            return;
          }
          const std::size_t bytes = std::min<std::size_t>(number("bytes"), pixels->count);
          std::string format = "unknown";
          const auto format_value = static_cast<uint32_t>(number("format"));
          for (const auto& n : ci->second.desc->value_names) {
            const char* text = n.field == "format" ? n.name_of(format_value) : nullptr;
            if (text == nullptr) continue;
            const std::string_view v = text;
            format = v == "RGB8" ? "rgb" : v == "MONO8" ? "mono" : v == "JPEG" ? "jpeg" : "unknown";
          }
          const auto* data = reinterpret_cast<const uint8_t*>(sample.data() + pixels->offset);
          broadcast(dump(json{{"type", "image"},
                              {"component", address_text(Address(raw))},
                              {"system", comp.system},
                              {"time_ns", sh.time_ns},
                              {"width", number("width")},
                              {"height", number("height")},
                              {"frame", number("frame")},
                              {"dropped", number("dropped")},
                              {"bad_frames", number("bad_frames")},
                              {"format", format},
                              {"data", base64(std::vector<uint8_t>(data, data + bytes))}}));
        },
        image_mailbox.address());
  }

  // Fixed-capacity arrays are sent only up to their count (a scan of 541 beams, not
  // 1081 slots): a fifth of the bytes on a robot's Wi-Fi or SSH tunnel.
  static void trim_arrays(const std::string& cls, json& d) {
    const auto cut = [&d](const char* count, std::initializer_list<const char*> arrays) {
      if (!d.contains(count) || !d[count].is_number_unsigned()) return;
      const auto n = d[count].get<std::size_t>();
      for (const char* a : arrays) {
        if (d.contains(a) && d[a].is_array() && d[a].size() > n)
          d[a].erase(d[a].begin() + static_cast<std::ptrdiff_t>(n), d[a].end());
      }
    };
    if (cls == kLadar) cut("beam_count", {"range", "intensity"});
    if (cls == "Scan2D") cut("point_count", {"x", "y", "range", "bearing", "type"});
    if (cls == "Path") {
      cut("point_count", {"x", "y"});
      cut("waypoint_count", {"waypoint_x", "waypoint_y"});
    }
    if (cls == kMcl) cut("shown", {"particle_x", "particle_y", "particle_phi", "particle_weight"});
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

  // The first component of a class (by the name its description gives) in a robot
  // (lowest instance), preferring one that answers.
  std::optional<Address> find(uint8_t system, std::string_view cls) const {
    std::optional<Address> best;
    bool best_alive = false;
    const int64_t now = rt::monotonic_ns();
    for (const auto& [raw, c] : components) {
      const Address a(raw);
      if (a.system() != system || class_of(a) != cls) continue;
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
      for (const char* cls : {kMcl, kLadar, kChassis}) {
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
      case Op::kCommand: command(client, r); break;
      case Op::kTrace: trace(client, r); break;
      case Op::kSetPose: set_pose(client, r); break;
      case Op::kJoystick: joystick(client, r); break;
      case Op::kJoystickRelease: {
        Robot& robot = robots[r.system];
        if (robot.joystick_owner == client || robot.joystick_owner == 0) stop_joystick(r.system);
        result(client, r, true, "joystick released: robot stopped");
        break;
      }
      case Op::kCommandJson: class_command(client, r); break;
    }
  }

  // The class command `name` of the component at `a`, its body's fields by name from
  // `fields` (through the class's description: rack-gui links no class, so the
  // panels send Pilot's SET_DESTINATION or the chassis' MOVE as any plug-in's command).
  // "" when it was sent (`done` gets the reply), else why nothing was sent.
  std::string send_command(Address a, const std::string& name, const json& fields, ReplyHandler done) {
    const auto it = class_infos.find(a.raw() & 0xFFFF0000u);
    if (it == class_infos.end() || !it->second.desc) {
      (void)described(a);
      return address_text(a) + ": " + name + ": its class description is not known yet (asked; try again)";
    }
    const rack::ClassDescription& d = *it->second.desc;
    const rack::CommandDescription* c = d.find_command(name);
    if (c == nullptr) return address_text(a) + ": class " + d.class_name + " describes no command " + name;
    std::vector<std::byte> body;
    const std::string why = encode_command_body(fields, c->body ? &*c->body : nullptr, body);
    if (!why.empty()) return address_text(a) + ": " + name + ": " + why + " (not sent)";
    const tims::ConstBuffer part{body.data(), body.size()};
    // The body is copied into the mailbox by send(): a local is fine.
    request(a, c->type, std::span<const tims::ConstBuffer>(&part, body.empty() ? 0 : 1), default_timeout(),
            std::move(done));
    return "";
  }

  // A class command by name (Foxglove services, rack-foxglove's player): the body is
  // encoded against the class description's type for it and sent only when it fits.
  void class_command(uint64_t client, const Request& r) {
    const Address a = r.component;
    const auto it = class_infos.find(a.raw() & 0xFFFF0000u);
    if (it == class_infos.end() || !it->second.desc) {
      result(client, r, false, address_text(a) + ": its class description is not known (yet): no command sent");
      return;
    }
    const rack::ClassDescription& d = *it->second.desc;
    const rack::CommandDescription* c = d.find_command(r.command);
    if (c == nullptr) {
      std::string known;
      for (const auto& k : d.commands) known += (known.empty() ? "" : ", ") + k.name;
      result(client, r, false,
             address_text(a) + ": class " + d.class_name + " has no command " + r.command +
                 " (it has: " + (known.empty() ? "none" : known) + ")");
      return;
    }
    std::vector<std::byte> body;
    const std::string why = encode_command_body(r.body, c->body ? &*c->body : nullptr, body);
    if (!why.empty()) {
      result(client, r, false, address_text(a) + ": " + r.command + ": " + why + " (not sent)");
      return;
    }
    const tims::ConstBuffer part{body.data(), body.size()};
    const std::string name = r.command;
    request(a, c->type, std::span<const tims::ConstBuffer>(&part, body.empty() ? 0 : 1), default_timeout(),
            [this, client, r, a, name](const Reply* rep) {
              const bool ok = rep != nullptr && rep->header.type == msg::kOk;
              result(client, r, ok, ok ? address_text(a) + ": " + name + " done" : failure(rep, name, a));
            });
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

  void joystick(uint64_t client, const Request& r) {
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

  void send_move(uint8_t system, double vx, double omega) {
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

  void run_gdos() {
    std::unique_ptr<tims::GdosSubscriber> sub;
    const std::string url = config.gdos_url.empty() ? config.lcm_url : config.gdos_url;
    const std::string channel = config.gdos_channel.empty() ? tims::kGdosChannel : config.gdos_channel;
    try {
      // A keyed network's log is signed: the same key file verifies it (as `gdos --key-file`).
      sub = std::make_unique<tims::GdosSubscriber>(url, channel, true, "rack-gui",
                                                   url == config.lcm_url ? config.key_file : std::string());
    } catch (const std::exception& e) {
      std::fprintf(stderr, "rack-gui: GDOS: %s\n", e.what());
      broadcast(dump(json{{"type", "notice"}, {"level", "error"}, {"text", std::string("GDOS: ") + e.what()}}));
      return;
    }
    while (running.load()) {
      std::vector<std::string> lines;
      try {
        sub->poll(100, [&](const tims::GdosRecord& r) {
          std::string name = r.name;
          if (name.empty()) name = sub->announced_name(r.source);
          std::string cls;  // the source's class as it describes itself (described())
          {
            const std::lock_guard lock(greet_mutex);
            const auto it = class_names.find(r.source & 0xFFFF0000u);
            if (it != class_names.end()) cls = it->second;
          }
          lines.push_back(gdos_view::json_line(r, name, cls));
        });
      } catch (const std::exception& e) {
        std::fprintf(stderr, "rack-gui: GDOS: %s\n", e.what());
      }
      const std::string w = sub->take_warnings();
      if (!w.empty()) broadcast(dump(json{{"type", "notice"}, {"level", "warning"}, {"text", "GDOS: " + w}}));
      if (lines.empty()) continue;
      {
        const std::lock_guard lock(greet_mutex);
        for (const auto& l : lines) {
          recent_log.push_back(l);
          if (recent_log.size() > kRecentLog) recent_log.pop_front();
        }
      }
      broadcast(gdos_message(lines.begin(), lines.end()));
    }
  }

  // Every 2 s: the reports that were added to a report file since the last look are
  // symbolized, and only those (rackd appends; a file of 1830 reports took 32 s to
  // symbolize again whenever one was added). The new part goes to rack-backtrace with
  // the file's header and module lines and the old reports blanked out, so its
  // "file:line" references stay those of the real file. A report still being written
  // (no `end` line yet) waits for the next look; one that stays incomplete for a whole
  // look is passed on as it is (rack-backtrace then says it is truncated).
  struct ReportFileState {
    std::uintmax_t size = 0;
    std::filesystem::file_time_type mtime;
    std::size_t done = 0;    // bytes symbolized so far (whole lines)
    bool tail_seen = false;  // an incomplete tail was there at the last look
  };
  void run_reports() {
    std::map<std::string, ReportFileState> seen;
    bool warned = false;
    while (running.load()) {
      std::error_code ec;
      std::vector<std::filesystem::path> files;
      for (std::filesystem::directory_iterator it(config.reports_dir, ec), end; !ec && it != end; it.increment(ec)) {
        const auto name = it->path().filename().string();
        if (name.rfind("rackd-", 0) == 0 && it->path().extension() == ".report") files.push_back(it->path());
      }
      if (ec && !warned && ec != std::errc::no_such_file_or_directory) {
        std::fprintf(stderr, "rack-gui: reports: %s: %s\n", config.reports_dir.c_str(), ec.message().c_str());
        warned = true;
      }
      bool changed = false;
      for (const auto& f : files) {
        if (!running.load()) break;
        std::error_code e1, e2;
        const auto size = std::filesystem::file_size(f, e1);
        const auto mtime = std::filesystem::last_write_time(f, e2);
        if (e1 || e2) continue;
        auto& st = seen[f.string()];
        const bool same = st.size == size && st.mtime == mtime;
        if (same && (st.done >= size || !st.tail_seen)) {
          if (st.done < size) st.tail_seen = true;  // complete it at the next look if it stays so
          continue;
        }
        if (size < st.done) {  // cut or replaced: start again
          st = ReportFileState{};
          const std::lock_guard lock(greet_mutex);
          report_texts.erase(f.string());
        }
        const bool flush_tail = same && st.tail_seen;
        st.size = size;
        st.mtime = mtime;
        const std::size_t before = st.done;
        const auto t0 = std::chrono::steady_clock::now();
        const std::string added = symbolize_new(f.string(), st, flush_tail);
        if (added.empty()) continue;
        const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::fprintf(stderr, "rack-gui: reports: %s: bytes %zu..%zu symbolized in %.2f s\n", f.string().c_str(), before,
                     st.done, took);
        const std::lock_guard lock(greet_mutex);
        std::string& text = report_texts[f.string()];
        text += added;
        if (text.size() > kMaxReportText) {
          std::size_t cut = text.size() - kMaxReportText;
          cut = text.find('\n', cut);
          text = "(older reports left out here: rack-backtrace " + f.string() + " shows them all)\n" +
                 (cut == std::string::npos ? std::string() : text.substr(cut + 1));
        }
        changed = true;
      }
      if (changed) broadcast(reports_message());
      for (int i = 0; i < 20 && running.load(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  }
  static constexpr std::size_t kMaxReportText = 256 * 1024;  // per file: the newest reports

  // The part of `file` after st.done up to its last complete report (or to its end
  // when `flush_tail`), symbolized; st.done moves past it. "" when nothing new.
  std::string symbolize_new(const std::string& file, ReportFileState& st, bool flush_tail) {
    std::string bytes;
    {
      std::FILE* in = std::fopen(file.c_str(), "rb");
      if (in == nullptr) return "";
      char buf[65536];
      std::size_t n = 0;
      while ((n = std::fread(buf, 1, sizeof buf, in)) > 0 && bytes.size() < (64u << 20)) bytes.append(buf, n);
      std::fclose(in);
    }
    if (bytes.size() <= st.done) return "";
    // The end of the last complete report ("end N" line) after st.done.
    std::size_t cut = st.done;
    for (std::size_t at = st.done; at < bytes.size();) {
      const auto nl = bytes.find('\n', at);
      if (nl == std::string::npos) break;
      if (bytes.compare(at, 4, "end ") == 0) cut = nl + 1;
      at = nl + 1;
    }
    if (flush_tail) cut = bytes.size();
    st.tail_seen = cut < bytes.size();
    if (cut == st.done) return "";
    // The header and module lines of the part already done, its other lines blank.
    std::string input;
    input.reserve(cut);
    for (std::size_t at = 0; at < st.done;) {
      auto nl = bytes.find('\n', at);
      if (nl == std::string::npos || nl >= st.done) nl = st.done;
      if (at == 0 || bytes.compare(at, 7, "module ") == 0) input.append(bytes, at, nl - at);
      input += '\n';
      at = nl + 1;
    }
    input.append(bytes, st.done, cut - st.done);
    st.done = cut;
    char tmp[] = "/tmp/rack-gui-report-XXXXXX";
    const int fd = mkstemp(tmp);
    if (fd < 0) return "rack-gui: cannot write a temporary file: " + std::string(std::strerror(errno)) + "\n";
    bool written = true;
    for (std::size_t off = 0; off < input.size();) {
      const ssize_t w = ::write(fd, input.data() + off, input.size() - off);
      if (w <= 0) {
        written = false;
        break;
      }
      off += static_cast<std::size_t>(w);
    }
    ::close(fd);
    std::string out = written ? symbolize(tmp) : "rack-gui: cannot write a temporary file\n";
    ::unlink(tmp);
    // Its name in rack-backtrace's text is the real file's.
    const std::string t = tmp;
    for (auto at = out.find(t); at != std::string::npos; at = out.find(t, at + file.size()))
      out.replace(at, t.size(), file);
    return out;
  }

  std::string backtrace_program() const {
    if (!config.backtrace_path.empty()) return config.backtrace_path;
    std::error_code ec;
    const auto self = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path();
    // Installed: beside rack-gui; in a build tree: tools/rack-backtrace next to tools/gui/.
    for (const auto& candidate : {self / "rack-backtrace", self.parent_path() / "rack-backtrace"}) {
      if (!ec && access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
    return "rack-backtrace";  // on PATH
  }

  // rack-backtrace FILE, its output (and errors), at most kMaxReportText. Its own
  // process, read with a 100 ms poll: stop() ends it (SIGKILL) instead of waiting for
  // it, so rack-gui exits promptly while a large file is being symbolized.
  std::string symbolize(const std::string& file) const {
    const std::string program = backtrace_program();
    int pipe_fd[2];
    if (pipe(pipe_fd) != 0) return "cannot run rack-backtrace: " + std::string(std::strerror(errno)) + "\n";
    const pid_t pid = fork();
    if (pid < 0) {
      ::close(pipe_fd[0]);
      ::close(pipe_fd[1]);
      return "cannot run rack-backtrace: " + std::string(std::strerror(errno)) + "\n";
    }
    if (pid == 0) {
      ::dup2(pipe_fd[1], 1);
      ::dup2(pipe_fd[1], 2);
      ::close(pipe_fd[0]);
      ::close(pipe_fd[1]);
      const char* argv[] = {program.c_str(), file.c_str(), nullptr};
      ::execvp(argv[0], const_cast<char* const*>(argv));  // NOLINT: execvp's signature
      std::fprintf(stderr, "cannot run %s: %s\n", program.c_str(), std::strerror(errno));
      ::_exit(127);
    }
    ::close(pipe_fd[1]);
    std::string out;
    bool stopped = false;
    for (;;) {
      if (!running.load()) {
        ::kill(pid, SIGKILL);
        stopped = true;
        break;
      }
      pollfd p{pipe_fd[0], POLLIN, 0};
      const int ready = ::poll(&p, 1, 100);
      if (ready < 0 && errno != EINTR) break;
      if (ready <= 0) continue;
      char buf[4096];
      const ssize_t n = ::read(pipe_fd[0], buf, sizeof buf);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      if (out.size() < kMaxReportText) out.append(buf, static_cast<std::size_t>(n));
    }
    ::close(pipe_fd[0]);
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (stopped) return "";
    if (status != 0 && out.empty()) out = "rack-backtrace failed (status " + std::to_string(status) + ")\n";
    return out;
  }

  std::string reports_message() {
    json list = json::array();
    const std::lock_guard lock(greet_mutex);
    for (const auto& [file, text] : report_texts) list.push_back({{"file", file}, {"text", text}});
    return dump(json{{"type", "reports"}, {"dir", config.reports_dir}, {"reports", list}});
  }

  template <typename It>
  static std::string gdos_message(It first, It last) {
    std::string m = "{\"type\":\"gdos\",\"records\":[";
    for (It it = first; it != last; ++it) {
      if (it != first) m += ',';
      m += *it;
    }
    return m + "]}";
  }

  void greet(uint64_t client) {
    send_to(client, dump(json{{"type", "hello"}, {"version", 1}, {"lcm", config.lcm_url}}));
    const std::lock_guard lock(greet_mutex);
    if (!last_components.empty()) send_to(client, last_components);
    for (const auto& [k, m] : class_messages) send_to(client, m);
    for (const auto& [s, m] : map_messages) send_to(client, m);
    if (!recent_log.empty()) send_to(client, gdos_message(recent_log.begin(), recent_log.end()));
    if (!report_texts.empty()) {
      json list = json::array();
      for (const auto& [file, text] : report_texts) list.push_back({{"file", file}, {"text", text}});
      send_to(client, dump(json{{"type", "reports"}, {"dir", config.reports_dir}, {"reports", list}}));
    }
  }

  BackendConfig config;
  Sink sink;
  tims::Router router{tims::kToolSystem};
  // rack-gui's mailbox addresses (0 replies, 1 images), held by no other tool while it
  // runs (rack/tims/tool_address.h).
  tims::ToolAddressClaim address_claim;
  tims::Mailbox reply_mailbox;
  tims::Mailbox image_mailbox;
  tims::Endpoint endpoint;
  tims::LcmTransport transport;
  std::vector<std::byte> buffer;
  std::vector<std::byte> image_buffer;
  std::atomic<bool> running{false};
  std::thread worker, gdos_thread, reports_thread;

  // Worker thread only.
  std::vector<Pending> pending;
  std::map<uint32_t, Component> components;
  std::map<uint32_t, ClassInfo> class_infos;  // system << 24 | class id << 16 (described())
  std::map<uint32_t, std::vector<std::pair<uint64_t, Request>>> class_waiters;
  std::vector<std::pair<int64_t, std::function<void()>>>
      deferred;  // worker thread only (defer())  // get_class before it is known
  std::map<std::string, Host> hosts;
  std::map<uint8_t, Robot> robots;

  std::mutex queue_mutex;  // server thread -> worker
  std::deque<std::pair<uint64_t, Request>> queue;
  std::vector<uint64_t> closed_clients;

  std::mutex greet_mutex;  // worker and GDOS thread -> server thread (new clients)
  std::string last_components;
  std::map<uint8_t, std::string> map_messages;
  std::map<uint32_t, std::string> class_messages;  // "class" messages by system and class id
  std::map<uint32_t, std::string> class_names;     // described class names (the GDOS thread's sources)
  std::deque<std::string> recent_log;
  std::map<std::string, std::string> report_texts;  // report file -> rack-backtrace's output

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
  const std::lock_guard lock(impl_->counters_mutex);
  return impl_->counters;
}

}  // namespace rack::gui
