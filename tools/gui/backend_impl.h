// rack-gui's link to the robots (backend.h): Backend::Impl, and the types its parts
// share. One concept per file:
//   backend.cpp           the worker thread, TiMS requests and replies, the ops (handle)
//   backend_state.cpp     discovery, component states, statistics, class descriptions
//   backend_data.cpp      the polled samples and images, the maps
//   backend_streams.cpp   "subscribe": component streams at their full rate
//   backend_commands.cpp  class commands, traces, all off, set pose, the joystick
//   report_watcher.*, gdos_relay.*  the report files and the GDOS log (threads of their own)
// Private to rack-gui's backend (tools/gui/backend*.cpp).
//
// Not RT code (a tool). Thread-safety: as backend.h says; every member marked "worker
// thread only" is touched by the worker alone.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <unordered_map>
#include <string_view>
#include <utility>

#include "gdos_relay.h"
#include "report_watcher.h"
#include "reply_matcher.h"
#include "rack/client/session.h"
#include "rack/core/class_description.h"
#include "rack/core/trace_session.h"
#include "rack/core/parameters.h"
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
#include "backend.h"

namespace rack::gui {

// What backend*.cpp share (was the anonymous namespace of backend.cpp).
namespace backend_detail {

using nlohmann::json;
using tims::Address;
namespace msg = tims::msg;
namespace rtrace = rack::trace;

constexpr uint32_t kSlotSize = 64 * 1024;  // the largest polled sample (Path) is ~17 KiB
constexpr uint32_t kReplySlots = 256;      // a poll round asks every component at once
// Camera images (0.9 MB): their replies go to a mailbox of their own with large slots.
// rack-gui links no class: the image's size is its class description's (a camera
// whose samples do not fit is shown without its image).
constexpr uint32_t kImageSlotSize = 2 * 1024 * 1024;
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

inline std::string class_text(Address a) {
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
constexpr const char* kScan2d = "Scan2D";
constexpr const char* kPath = "Path";

inline std::string base64(const std::vector<uint8_t>& in) {
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

inline std::string param_text(const char* s, std::size_t n) { return std::string(s, strnlen(s, n)); }

inline json param_json(const wire::ParamRecord& p) {
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

inline std::string dump(const json& j) { return j.dump(-1, ' ', false, json::error_handler_t::replace); }

// A class description as JSON, for tools that build on rack-gui's protocol (the
// Foxglove bridge, tools/foxglove, makes each class's JSON schema from it):
//   {"type":"class","system":0,"class_id":21,"class":"Chassis","impl":"ChassisSim",
//    "summary":..,"data":{"name":"ChassisData","size":120,"fields":[{"name":"vx",
//    "kind":"f64","count":1},..]} (null: no samples),"commands":[{"name":"MOVE",
//    "type":21,"summary":..,"body":{..} or null}],"parameters":[{"name":..,"kind":..,
//    "unit":..,"min":..,"max":..,"default":..,"doc":..,"choices":[..]}]}
// Field kinds: i8 u8 bool char i16 u16 i32 u32 i64 u64 f32 f64 (char arrays are strings).
inline json type_json(const rack::TypeDescription& t) {
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
inline std::string class_message(uint8_t system, const rack::ClassDescription& d,
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
  bool failed = false;   // refused or malformed: asked again only after kClassRetryNs
  int64_t failed_ns = 0;
  bool failure_said = false;  // the failure written to stderr (once)
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

}  // namespace backend_detail
using namespace backend_detail;  // NOLINT: private header of backend*.cpp

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
    // A sequence number that no other request to this mailbox holds, waiting or timed
    // out recently (reply_matcher.h): a late reply takes no later request. A mailbox
    // with every number taken is not asked: the request fails at once, as a timeout.
    const uint32_t key = dest.component().raw();
    const int64_t now = rt::monotonic_ns();
    const uint64_t token = next_token++;
    const std::optional<uint8_t> seq = replies.open(key, token, now + timeout_ns, now);
    {
      const std::lock_guard lock(counters_mutex);
      ++counters.requests;
      if (!seq) ++counters.no_sequence;
    }
    if (!seq) {
      done(nullptr);
      return;
    }
    std::size_t length = 0;
    for (const auto& part : body) length += part.size;
    const tims::MessageHeader h = tims::make_header(dest, reply_to == Address() ? endpoint.address() : reply_to, type,
                                                    endpoint.priority(), *seq, length);
    if (!tims::delivered(endpoint.router().send(h, body))) {
      replies.cancel(key, *seq);
      done(nullptr);
      return;
    }
    reply_handlers.emplace(token, std::move(done));
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

  // Hands a received reply to the request it answers (reply_matcher.h: by source,
  // sequence number and being a reply); a late or unmatched one is counted and dropped.
  void dispatch(const tims::Mailbox::Received& got, std::span<const std::byte> buf);

  void receive_replies(int64_t wait_ns);

  // Describes a failed or refused reply for the user.
  std::string failure(const Reply* r, const std::string& what, Address dest) const;

  // ------------------------------------------------------------ discovery and state
  void refresh_hosts();

  // A host the network stopped announcing (it stopped, cleanly or not, and discovery
  // expired it) is shown as NOT ANSWERING for config.host_forget_ms, then leaves the
  // list with its components, and every browser is told so.
  void forget_silent_hosts();

  [[nodiscard]] std::string shown_state(const Component& c, int64_t now) const;

  void poll_status();

  void poll_stats();

  // The data task's latency histogram, with the stats: not for components whose stats
  // say they have no data task (their histogram is empty by definition).
  void poll_latency();

  // The description of a component's class (GET_CLASS: its pages one request at a
  // time, then decoded), per system and class id: every class's data view comes from
  // it, so a class rack-gui was not built with (a plug-in) shows its fields too.
  // nullptr until it is known; a component that refuses it is not asked again.
  const ClassInfo* described(Address a);

  void answer_class_waiters(uint32_t key, Address a, const rack::ClassDescription* d, const std::string& why);
  // Work for a later round of the worker (a trace that is still recording).
  void defer(int64_t delay_ns, std::function<void()> f);
  void run_deferred();

  // A live task timeline of one host (as `rackctl trace --duration S all`): TRACE_START
  // to the executor's trace mailbox, TRACE_READ until the JSON is ready, read in
  // chunks, checked to be JSON, then sent to the browser that asked.
  void trace(uint64_t client, const Request& r);
  void trace_read(uint64_t client, const Request& r, Address t, const std::string& host_name,
                  const std::shared_ptr<std::string>& text, int64_t give_up);

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
                                      std::vector<std::byte>& body);
  static std::string json_body(const Request& r, const rack::TypeDescription* type, std::vector<std::byte>& body);

  void class_command(uint64_t client, const Request& r);

  // The class command `name` of the component at `a`, its body's fields by name from
  // `fields` (through the class's description: rack-gui links no class, so the
  // panels send Pilot's SET_DESTINATION or the chassis' MOVE as any plug-in's command).
  // "" when it was sent (`done` gets the reply), else why nothing was sent.
  std::string send_command(Address a, const std::string& name, const json& fields, ReplyHandler done);

  // The name of a's class: TiMS' name (the executor's, tools'), else its
  // description's, else Class0xNN (not described yet).
  std::string class_of(Address a) const;
  // An address as the page shows it and sends it back: its class by name (Counter(2/0),
  // a plug-in's as a built-in's); resolve_component() reads it.
  std::string address_text(Address a) const { return rack::client::address_text(a, class_of(a)); }

  // A request's component given by a class name TiMS does not know (every component
  // class: rack-gui links none), as the page sends it: the component at that system
  // and instance whose class describes itself with that name (or implementation
  // name). False, with the client answered, when none is known (yet).
  bool resolve_component(uint64_t client, Request& r);
  // Data the dashboard draws: the navigation classes every round, other classes with
  // a data type every `slow` rounds.
  void poll_data(uint64_t round);

  // A DATA message's sample (SampleHeader, then the class's data type) as a "data"
  // message for the browsers, decoded with the class description's field names;
  // nullopt when it does not decode (wrong size, class not described).
  std::optional<std::string> data_message(uint32_t raw, const Component& comp, const tims::MessageHeader& header,
                                          std::span<const std::byte> body, bool stream);

  // A camera's newest image, as {"type":"image",...} with the pixels (or JPEG) in base64.
  void poll_image(uint32_t raw);

  // Fixed-capacity arrays are sent only up to their count (a scan of 541 beams, not
  // 1081 slots): a fifth of the bytes on a robot's Wi-Fi or SSH tunnel.
  static void trim_arrays(const std::string& cls, json& d);

  std::string components_message() const;

  // The first component of a class (by the name its description gives) in a robot
  // (lowest instance), preferring one that answers.
  std::optional<Address> find(uint8_t system, std::string_view cls) const;

  // ------------------------------------------------------------ maps
  void poll_maps();

  std::optional<std::string> configured_map(uint8_t system) const;

  void load_and_send_map(uint8_t system, const std::string& file, const std::string& from);

  // ------------------------------------------------------------ client requests
  void handle(uint64_t client, const Request& r);

  // ------------------------------------------------------------ streams
  // "subscribe": the client is added to the component's stream (opened when it is
  // the first); answered when the producer answers (or at once when it streams already
  // at the period asked for).
  void subscribe(uint64_t client, const Request& r);

  // GET_CONT_DATA into the stream mailbox: a new subscription, a renewal of its lease
  // or a new period (the producer keeps one listener per mailbox).
  void open_stream(uint32_t raw);

  void stop_stream(uint32_t raw);

  // Every poll round: renew the leases, take up streams the producers dropped.
  void maintain_streams();

  // A message of the stream mailbox: a sample goes to the stream's clients; an ERROR
  // (the producer left ENABLED, its host was lost) or the end of a replay's stream
  // ends the subscription until maintain_streams() takes it up again.
  void stream_sample(const tims::Mailbox::Received& got, std::span<const std::byte> buf);

  void all_off_step(uint64_t client, const Request& r, std::shared_ptr<std::vector<Address>> order, std::size_t i,
                    std::shared_ptr<std::vector<std::string>> failures);

  void set_pose(uint64_t client, const Request& r);

  void joystick(uint64_t client, const Request& r);

  void send_move(uint8_t system, double vx, double omega);

  void stop_joystick(uint8_t system);
  void release_joystick(uint8_t system);

  // Dead-man: the browser sends joystick commands ten times a second while the stick
  // is held; silence (a frozen tab, a lost network) stops the robot. The chassis
  // watchdog stops it as well should this tool die.
  void check_dead_man();

  // ------------------------------------------------------------ threads
  void run_worker();

  void greet(uint64_t client);

  BackendConfig config;
  Sink sink;
  tims::Router router{tims::kToolSystem};
  // rack-gui's mailbox addresses (0 replies, 1 images, 2 and 3 streams), held by no other tool while it
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
  // The requests waiting for their replies: their numbers, and their handlers by token.
  // A late reply can still come this long after its request timed out (a host that was
  // busy or cut off): its number is not given to another request to that mailbox
  // before.
  static constexpr int64_t kReplyQuarantineNs = 30 * rt::kNsPerSec;
  ReplyMatcher replies{kReplyQuarantineNs};
  std::unordered_map<uint64_t, ReplyHandler> reply_handlers;
  uint64_t next_token = 1;
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
  void refuse(uint64_t client, const ParseError& e);
};

}  // namespace rack::gui
