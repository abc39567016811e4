// rack-gui's link to the robots: one non-RT thread that joins the TiMS/LCM network
// as a tool (as rackctl does), keeps the list of every component of every host with
// its state, polls the data the dashboard draws, and carries out the browser's
// requests (parsed by gui_protocol.h) as asynchronous TiMS requests, so one robot
// that does not answer never delays the others.
//
// What the browser sees of a component's state:
//   "enabled", "disabled", "error": its last GET_STATUS reply, at most kStaleNs old;
//   "no_reply": no reply for kStaleNs (the host stopped answering, or vanished from
//               discovery: it is kept in the list, never shown with its last state);
//   "not_available": the network answered NOT_AVAILABLE for it.
//
// A component's address text (in "components", "data", "class" messages) names its
// class by number, Class0x11(0/0), until its class description has come, and by the
// name the description gives, Ladar(0/0), after (rack-gui links no class): a client
// takes each "components" message as the whole list (it lists every component), and
// follows a component it chose by robot, host and name. Requests may carry either form.
//
// A host that the network no longer announces is kept (its components "no_reply") for
// host_forget_ms, then removed from the list with its components, and the browsers are
// told so.
//
// A reports thread symbolizes the report files in `reports_dir` with rack-backtrace
// (report_watcher.h).
//
// Class descriptions (GET_CLASS) are passed to the browsers ("class" messages) for the
// plots and the command panel; a "command" is encoded from the description as
// `rackctl send` does; a "trace" runs TRACE_START/TRACE_READ on a host's executor as
// `rackctl trace` does, its reads deferred to later rounds while the host records.
//
// A "subscribe" opens a component's data stream (GET_CONT_DATA into a mailbox of its
// own, at the producer's rate or a period): every sample goes to the clients that
// subscribed, as a "data" message with "stream":true (tools/foxglove records them).
// The subscription is renewed within its lease, taken up again when the producer
// dropped it and is enabled again, and stopped when its last client leaves.
//
// A GDOS thread receives the log of every host and passes it on in batches; the last
// records are kept for browsers that connect later (gdos_relay.h).
//
// Not RT code (a tool). Thread-safety: submit(), client_closed() and
// snapshot_for_new_client() may be called from any thread; the sink is called from
// the backend's threads.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "gui_protocol.h"

namespace rack::gui {

struct BackendConfig {
  std::string lcm_url;            // TiMS network
  std::string key_file;           // the network's link key (authenticated links); "" = none
  std::string gdos_url;           // "" = lcm_url
  std::string gdos_channel;       // "" = RACK_GDOS
  std::vector<std::string> maps;  // --map SYSTEM=FILE or FILE (every robot)
  std::string map_root = ".";     // where relative `map` parameters are looked up
  // Mode-switch and crash report files (rackd-*.report) of the hosts on this machine,
  // symbolized with rack-backtrace as reports are added. "" disables it.
  std::string reports_dir = "/var/tmp/rack";
  std::string backtrace_path;  // rack-backtrace; "" = beside rack-gui, else on PATH
  int poll_ms = 200;           // state and data poll period
  // A host no longer announced leaves the list (with its components) after this long;
  // until then it is shown as not answering. -1: never.
  int host_forget_ms = 30000;
  int timeout_ms = 1000;  // a request not answered in this time fails
};

class Backend {
 public:
  // Messages for one client (client id) or every client (id 0).
  using Sink = std::function<void(uint64_t client, std::string message)>;

  // Joins the network; throws std::runtime_error naming the URL on failure.
  Backend(BackendConfig config, Sink sink);
  ~Backend();
  Backend(const Backend&) = delete;
  Backend& operator=(const Backend&) = delete;

  void start();
  void stop();

  // A message from client `client` (any bytes): parsed here; a malformed one is
  // answered with an error and its reason at once, counted per reason, logged at most
  // once a second, and sends nothing to any robot. At most kMaxQueuedRequests wait
  // for the robots; beyond that a request is refused (Refusal::kBusy). Never throws.
  static constexpr std::size_t kMaxQueuedRequests = 256;
  void submit(uint64_t client, std::string_view text) noexcept;
  // A message the server refused before parsing (binary, too large): counted, logged
  // at most once a second, and answered when the client is still there.
  void refused(uint64_t client, Refusal reason, const std::string& message) noexcept;
  // The client went away: a joystick it held stops the robot.
  void client_closed(uint64_t client);
  // What a client that just connected needs (hello, components, maps, recent log).
  void greet(uint64_t client);

  struct Counters {
    uint64_t malformed = 0;                         // client messages refused (every reason)
    std::array<uint64_t, kRefusalKinds> refused{};  // by Refusal
    uint64_t requests = 0;                          // TiMS requests sent
    uint64_t timeouts = 0;                          // TiMS requests not answered in time
    uint64_t no_sequence = 0;                       // requests not sent: every sequence number of the mailbox taken
    uint64_t late_replies = 0;                      // replies after their request timed out, dropped
    uint64_t unmatched_replies = 0;                 // replies to no request of rack-gui (or not replies), dropped
    uint64_t bad_replies = 0;                       // replies that did not decode (GET_LATENCY), not passed on
    uint64_t streamed = 0;                          // stream samples passed on ("subscribe")
    uint64_t stream_lost = 0;                       // stream samples lost: the stream mailboxes were full
  };
  [[nodiscard]] Counters counters() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rack::gui
