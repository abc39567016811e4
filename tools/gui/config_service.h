// rack-gui's configuration tool (issue 25): the host files of the directories it was
// told to serve (--config DIR), drawn as a deployment graph with the allocation per
// CPU (rack/client/deployment.h, as `rackctl graph` and `rackctl alloc`), checked by
// the loader rackd uses (`rackd --check` on the edited text) and saved only when valid.
//
// Client -> server, JSON text on the dashboard's WebSocket, "op" beginning "config_"
// (main.cpp routes these here, everything else to the Backend), with an optional
// integer "id" echoed in the reply {"type":"config","op":...,"id":...,"ok":...}:
//
//   {"op":"config_files"}                         the served directories and their host files
//   {"op":"config_graph","dir":D}                 D's deployment: JSON, DOT, SVG (graphviz), allocation
//   {"op":"config_graph","dir":D,"live":true}     the same with what the network says (rackctl --live:
//                                                 stale hosts, state, utilisation, worst wake-up latency)
//   {"op":"config_graph","live":true}             no "dir": the deployment as it runs, from discovery
//                                                 alone (rackctl graph/alloc --live without host files:
//                                                 tasks, CPUs, flows and networks as they run)
//   {"op":"config_classes"}                       `rackd --list-classes --json` with every served host file
//                                                 (the editor's forms; the plug-in classes they name described too)
//   {"op":"config_load","file":F}                 F's text
//   {"op":"config_check","file":F,"text":T}       rackd --check on T (as F): errors with line and column
//   {"op":"config_save","file":F,"text":T}        the same, and T replaces F only when rackd accepts it
//                                                 (config_load and a save answer F's "disk_version";
//                                                 check and save with "base_version":V answer
//                                                 "disk_changed": F is no longer what V was, and a
//                                                 save is then refused: "save_error")
//   {"op":"config_part","upload":U,"index":I,"count":N,"text":T}
//                                                 part I (0..N-1, in order) of a text above one WebSocket
//                                                 message (64 KiB); answered {"received":I+1}. Then
//   {"op":"config_check"|"config_save","file":F,"upload":U}  uses the assembled text (once).
//                                                 Uploads: U is 1..32 letters or digits; at most
//                                                 kMaxUploads at once (the oldest gives way), N <=
//                                                 kMaxUploadParts, the whole at most a host file's
//                                                 1 MiB; a part out of order or too much drops it.
//
// What may be read and written: F names a file directly inside one of the served
// directories (the path as config_files lists it), called *.yaml or *.yml, its name
// of letters, digits, '.', '_' and '-' not beginning with '.'; an existing F must be a
// regular file, not a symbolic link. Anything else is refused with the reason. The
// text is checked in a temporary file beside F (so relative paths in it resolve as
// they will for F), with rackd's working directory F's directory, and that same file
// is renamed over F when valid (atomic: a reader sees the old file or the new one).
//
// Malformed messages are answered {"type":"config","ok":false,"error":...}; nothing is
// written then. Requests are carried out one at a time on the service's own thread
// (rackd and dot run as child processes with a time limit), so the I/O thread and the
// robot link never wait for them; at most kMaxQueued wait, more are refused as busy.
//
// Not RT code (a tool).
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "rack/client/deployment.h"

namespace rack::gui {

struct ConfigServiceConfig {
  std::vector<std::string> dirs;  // --config DIR: served directories (made absolute)
  std::string rackd_path;         // --rackd: "" = beside rack-gui, else on PATH
  std::string dot_path = "dot";   // graphviz
  // The live view (config_graph with "live": true) runs `rackctl graph --live` and
  // `rackctl alloc --live` on rack-gui's own network.
  std::string rackctl_path;  // "" = beside rack-gui, else on PATH
  std::string lcm_url;       // rack-gui's TiMS network
  std::string key_file;      // its key file ("" = none)
  int timeout_ms = 10000;    // a child process running longer is killed
};

class ConfigService {
 public:
  static constexpr std::size_t kMaxQueued = 16;
  static constexpr std::size_t kMaxUploads = 4;      // texts being sent in parts at once
  static constexpr uint64_t kMaxUploadParts = 1024;  // parts of one text
  using Sink = std::function<void(uint64_t client, std::string message)>;

  ConfigService(ConfigServiceConfig config, Sink sink);
  ~ConfigService();
  ConfigService(const ConfigService&) = delete;
  ConfigService& operator=(const ConfigService&) = delete;

  // Whether a client message is for this service (a JSON object whose "op" begins
  // "config_"). Never throws.
  [[nodiscard]] static bool handles(std::string_view text) noexcept;
  // Queues a request; the reply goes to the sink from the service's thread.
  void submit(uint64_t client, std::string text);
  // Carries out one request now and returns the reply (the thread's work; tests).
  [[nodiscard]] std::string handle(std::string_view text);

  // The served file a client names, or "" and `why` (the rules above).
  [[nodiscard]] std::string served_file(const std::string& file, std::string& why) const;

 private:
  void run();
  [[nodiscard]] std::string rackd_program() const;
  [[nodiscard]] std::string rackctl_program() const;

  ConfigServiceConfig config_;
  Sink sink_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::pair<uint64_t, std::string>> queue_;
  bool stop_ = false;
  // Per served directory (rackd --list-classes --json with its host files, so their
  // plug-in classes are described): the service thread's.
  std::map<std::string, std::vector<rack::deploy::ClassInfo>> class_info_;
  // Texts sent in parts (config_part), by upload id: the service thread's.
  struct Upload {
    uint64_t count = 0;
    uint64_t received = 0;
    std::string text;
    std::chrono::steady_clock::time_point started;
  };
  std::map<std::string, Upload> uploads_;
  std::thread thread_;
};

}  // namespace rack::gui
