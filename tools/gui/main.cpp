// rack-gui: the dashboard of every robot on a TiMS/LCM network, in the browser.
// Joins the network as a tool (like rackctl and gdos) and serves the built web
// front end (tools/gui/web, built by scripts/setup.sh) with a WebSocket for live data
// and commands. Not RT code.
#include <signal.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "backend.h"
#include "config_service.h"
#include "http_server.h"
#include "rack/client/session.h"
#include "rack/core/host_config.h"
#include "rack/tims/lcm_transport.h"
#include "rack/version.h"

#ifndef RACK_GUI_WEB_ROOT
#define RACK_GUI_WEB_ROOT ""
#endif

namespace {

constexpr const char* kUsage = R"(usage: rack-gui [options]

Serves RACK-RT's web dashboard: every component of every robot on the TiMS/LCM
network with its state (click: ON/OFF, "all off" per robot), parameters, the GDOS
log, a map with the robot's pose, particles, laser scan, path and destination
(click: set a destination or the robot's position), a software joystick, and
per-component timing. Open the printed address in a browser.

options:
  --address ADDR     listen address (default 127.0.0.1: this machine only; 0.0.0.0
                     for every interface: anyone who reaches the port can drive
                     the robots, so prefer an SSH tunnel, see the README)
  --port PORT        TCP port (default 8080; 0: any free port, printed at start)
  --lcm URL          TiMS/LCM network (default: $LCM_DEFAULT_URL, else
                     udpm://239.255.76.67:7667?ttl=0)
  --key-file FILE    the network's key file (authenticated links: the file the
                     host files name as key_file; default: $RACK_KEY_FILE); the
                     GDOS log on the same network is verified with it too
  --host-file FILE   take the network and its key file from a host file (its
                     first network); --lcm and --key-file override either
  --gdos-lcm URL     the network of the GDOS log (default: the TiMS network)
  --gdos-channel CH  the GDOS channel (default RACK_GDOS)
  --map [SYS=]FILE   the map (map_server YAML) to draw for robot SYS, or for every
                     robot without SYS= (repeatable). Default: the `map` parameter
                     of the robot's MCL (else its simulators), read relative to
                     --map-root
  --map-root DIR     where relative map paths of the robots are found (default:
                     the working directory; rackd reads them relative to its own)
  --reports DIR      mode-switch and crash report files of the rackd processes on
                     this machine (their crash_dir; default /var/tmp/rack),
                     symbolized with rack-backtrace for the "Mode switches" view;
                     --reports '' turns it off
  --backtrace PATH   the rack-backtrace program (default: beside rack-gui, else PATH)
  --web DIR          the built front end (default: tools/gui/web/dist of the source
                     tree it was built from, else <prefix>/share/rack-gui/web)
  --config DIR       serve the host files in DIR to the "Configuration" view
                     (repeatable): the deployment graph, the allocation per CPU,
                     and the editor, which saves a file of DIR only when rackd's
                     own check accepts it; "live" asks the network through the
                     rackctl beside rack-gui (README: "The configuration tool")
  --rackd PATH       the rackd that checks edited host files (default: beside
                     rack-gui, else PATH)
  --poll-ms MS       state and data poll period (default 200)
  --timeout-ms MS    a robot that does not answer within this is shown as
                     "no reply" (default 1000)
  --max-clients N    browsers and tools served at once (default 64, 1..10000): one
                     more is closed with WebSocket close code 1013 (try again
                     later) and the reason, and counted
  --forget-s SEC     a host the network no longer announces (it stopped) is shown
                     as NOT ANSWERING for SEC seconds, then leaves the list with
                     its components (default 30; -1: never)
  -h, --help         this text
  --version          the version (CMake project version, git describe)

Browser messages (WebSocket, JSON text; tools/gui/gui_protocol.h) that break the
protocol are refused with an error naming what, where and a reason (too_large,
not_json, too_deep, duplicate_key, not_object, bad_op, bad_key, bad_value, busy,
binary), logged at most once a second and counted by reason in the line printed at
exit; nothing reaches a robot. Over 64 KiB or not UTF-8 also ends that connection
(close code 1009 or 1007). At most 256 requests wait for the robots; more are
refused as busy. A client that does not read keeps at most 16 MiB of messages
waiting (the oldest are dropped, counted). A robot's reply is taken only by the
request it answers (mailbox, sequence number, a reply); one that comes after its
request timed out is dropped and counted.

environment:
  RACK_TOOL_REGISTRY  where tools on this machine claim their TiMS address (default
                      /tmp/rack-tool-addresses.lock; see rackctl --help)

exit codes: 0 stopped by SIGINT/SIGTERM, 1 cannot listen or join the network,
2 usage error.
)";

[[noreturn]] void usage_error(const std::string& what) {
  std::fprintf(stderr, "rack-gui: %s\n(rack-gui --help for the options)\n", what.c_str());
  std::exit(2);
}

long number(const std::string& opt, const std::string& v, long lo, long hi) {
  char* end = nullptr;
  errno = 0;
  const long n = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || errno != 0 || n < lo || n > hi) {
    usage_error(opt + " needs a number " + std::to_string(lo) + ".." + std::to_string(hi) + ", got '" + v + "'");
  }
  return n;
}

}  // namespace

int main(int argc, char** argv) {
  rack::gui::BackendConfig config;
  config.lcm_url = rack::client::default_lcm_url();
  if (const char* k = std::getenv("RACK_KEY_FILE"); k != nullptr) config.key_file = k;
  std::string host_file;
  bool lcm_given = false, key_given = false;
  std::string address = "127.0.0.1";
  long port = 8080;
  std::string web = RACK_GUI_WEB_ROOT;
  rack::gui::ConfigServiceConfig config_dirs;
  rack::gui::ServerLimits limits;
  bool web_given = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* what) -> std::string {
      if (i + 1 >= argc) usage_error(a + " needs " + what);
      return argv[++i];
    };
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--version") {
      rack::print_version("rack-gui");
      return 0;
    } else if (a == "--address") {
      address = value("an IP address");
    } else if (a == "--port") {
      port = number(a, value("a port"), 0, 65535);
    } else if (a == "--lcm") {
      config.lcm_url = value("an LCM URL");
      lcm_given = true;
    } else if (a == "--key-file") {
      config.key_file = value("a key file");
      key_given = true;
    } else if (a == "--host-file") {
      host_file = value("a host file");
    } else if (a == "--gdos-lcm") {
      config.gdos_url = value("an LCM URL");
    } else if (a == "--gdos-channel") {
      config.gdos_channel = value("a channel");
    } else if (a == "--map") {
      config.maps.push_back(value("[SYS=]FILE"));
    } else if (a == "--map-root") {
      config.map_root = value("a directory");
    } else if (a == "--reports") {
      config.reports_dir = value("a directory");
    } else if (a == "--backtrace") {
      config.backtrace_path = value("a program");
    } else if (a == "--web") {
      web = value("a directory");
      web_given = true;
    } else if (a == "--config") {
      const std::string dir = value("a directory of host files");
      std::error_code dir_ec;
      if (!std::filesystem::is_directory(dir, dir_ec)) usage_error("--config: '" + dir + "' is not a directory");
      config_dirs.dirs.push_back(dir);
    } else if (a == "--rackd") {
      config_dirs.rackd_path = value("the rackd program");
    } else if (a == "--poll-ms") {
      config.poll_ms = static_cast<int>(number(a, value("milliseconds"), 20, 10000));
    } else if (a == "--max-clients") {
      limits.max_clients = static_cast<std::size_t>(number(a, value("a number of clients"), 1, 10000));
    } else if (a == "--forget-s") {
      const long sec = number(a, value("seconds"), -1, 86400);
      config.host_forget_ms = sec < 0 ? -1 : static_cast<int>(sec * 1000);
    } else if (a == "--timeout-ms") {
      config.timeout_ms = static_cast<int>(number(a, value("milliseconds"), 50, 60000));
    } else {
      usage_error("unknown argument '" + a + "'");
    }
  }
  if (!host_file.empty()) {
    // The network and key of the host whose file this is, as rackctl --host-file.
    const rack::ToolNetwork net = rack::read_tool_network(host_file);
    if (!net.errors.empty()) usage_error(net.errors.front().str());
    if (!lcm_given) config.lcm_url = net.url;
    if (!key_given) config.key_file = net.key_file;
  }
  std::error_code ec;
  if (!web_given && !std::filesystem::is_regular_file(std::filesystem::path(web) / "index.html", ec)) {
    // An installed rack-gui: <prefix>/bin/rack-gui serves <prefix>/share/rack-gui/web.
    const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec) web = (self.parent_path().parent_path() / "share" / "rack-gui" / "web").string();
  }
  if (web.empty() || !std::filesystem::is_regular_file(std::filesystem::path(web) / "index.html", ec)) {
    std::fprintf(stderr,
                 "rack-gui: no built front end in '%s' (index.html missing): run scripts/setup.sh, or "
                 "'npm ci && npm run build' in tools/gui/web, or give --web DIR\n",
                 web.c_str());
    return 1;
  }

  // SIGINT/SIGTERM: handled on a thread of their own (sigwait), which stops the loop.
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  signal(SIGPIPE, SIG_IGN);

  try {
    rack::gui::HttpServer* server_ptr = nullptr;
    rack::gui::Backend backend(config, [&server_ptr](uint64_t client, std::string m) {
      if (server_ptr != nullptr) server_ptr->send(client, std::move(m));
    });
    rack::gui::ServerHandlers handlers;
    handlers.opened = [&backend](uint64_t c) { backend.greet(c); };
    // The configuration tool's requests ("op":"config_*") have their own service.
    config_dirs.lcm_url = config.lcm_url;
    config_dirs.key_file = config.key_file;
    auto config_service = std::make_unique<rack::gui::ConfigService>(config_dirs,
                                                                     [&server_ptr](uint64_t client, std::string m) {
                                                                       if (server_ptr != nullptr)
                                                                         server_ptr->send(client, std::move(m));
                                                                     });
    handlers.message = [&backend, &config_service](uint64_t c, const std::string& text) {
      if (rack::gui::ConfigService::handles(text)) config_service->submit(c, text);
      else backend.submit(c, text);
    };
    handlers.closed = [&backend](uint64_t c) { backend.client_closed(c); };
    handlers.refused = [&backend](uint64_t c, rack::gui::FrameRefusal why, std::size_t bytes) {
      if (why == rack::gui::FrameRefusal::kBinary) {
        backend.refused(c, rack::gui::Refusal::kBinary,
                        "binary WebSocket message of " + std::to_string(bytes) + " bytes; the protocol is JSON text");
      } else if (why == rack::gui::FrameRefusal::kNotUtf8) {
        backend.refused(c, rack::gui::Refusal::kNotJson,
                        "WebSocket text message is not UTF-8; connection closed (1007)");
      } else {
        backend.refused(c, rack::gui::Refusal::kTooLarge,
                        "WebSocket message over " + std::to_string(rack::gui::HttpServer::kMaxMessage) +
                            " bytes; connection closed (1009)");
      }
    };
    rack::gui::HttpServer server(address, static_cast<uint16_t>(port), web, handlers, limits);
    server_ptr = &server;
    backend.start();
    std::thread signals([&server, set] {
      int sig = 0;
      sigwait(&set, &sig);
      server.stop();
    });
    signals.detach();
    std::fprintf(stderr, "rack-gui: serving http://%s:%u/ (TiMS on %s)\n", address.c_str(), server.port(),
                 config.lcm_url.c_str());
    std::fflush(stderr);
    server.run();
    config_service.reset();  // its thread ends before the server goes
    backend.stop();
    server_ptr = nullptr;
    const auto c = backend.counters();
    std::string by_reason;
    for (std::size_t k = 0; k < c.refused.size(); ++k) {
      if (c.refused[k] == 0) continue;
      by_reason += (by_reason.empty() ? " (" : ", ") +
                   std::string(rack::gui::describe(static_cast<rack::gui::Refusal>(k))) + " " +
                   std::to_string(c.refused[k]);
    }
    if (!by_reason.empty()) by_reason += ")";
    std::fprintf(
        stderr,
        "rack-gui: stopped; %llu request(s) sent, %llu not answered in time, %llu malformed client message(s)%s, "
        "%llu malformed reply(ies), %llu stream sample(s) passed on, %llu lost (rack-gui too slow)\n",
        static_cast<unsigned long long>(c.requests), static_cast<unsigned long long>(c.timeouts),
        static_cast<unsigned long long>(c.malformed), by_reason.c_str(), static_cast<unsigned long long>(c.bad_replies),
        static_cast<unsigned long long>(c.streamed), static_cast<unsigned long long>(c.stream_lost));
    std::fprintf(stderr,
                 "rack-gui: %llu WebSocket client(s) refused (--max-clients), %llu message(s) dropped for clients "
                 "that did not read\n",
                 static_cast<unsigned long long>(server.refused_clients()),
                 static_cast<unsigned long long>(server.dropped_messages()));
    std::fprintf(stderr,
                 "rack-gui: %llu late and %llu unmatched TiMS reply(ies) dropped, %llu request(s) not sent (every "
                 "sequence number of the mailbox taken)\n",
                 static_cast<unsigned long long>(c.late_replies), static_cast<unsigned long long>(c.unmatched_replies),
                 static_cast<unsigned long long>(c.no_sequence));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rack-gui: %s\n", e.what());
    return 1;
  }
  return 0;
}
