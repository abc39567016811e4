// rack-gui's server without a browser (so these paths are covered where Chromium is
// missing): static files and the WebSocket of HttpServer with a Boost.Beast client,
// and the real rack-gui refusing malformed WebSocket messages on a private LCM bus.
#include <gtest/gtest.h>
#include <signal.h>

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "http_server.h"
#include "process.h"
#include "ws_client.h"

namespace rack::test {
namespace {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;
using namespace std::chrono_literals;

// A raw GET (the target is sent as given, no normalisation): status and body.
std::pair<int, std::string> get(uint16_t port, const std::string& target) {
  net::io_context ioc;
  beast::tcp_stream s(ioc);
  s.connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port));
  s.expires_after(5s);
  http::request<http::empty_body> req(http::verb::get, target, 11);
  req.set(http::field::host, "127.0.0.1");
  http::write(s, req);
  beast::flat_buffer buf;
  http::response<http::string_body> res;
  http::read(s, buf, res);
  return {static_cast<int>(res.result_int()), res.body()};
}

// The real rack-gui's command line: a free port, an empty web root in `dir`, no crash
// reports, then `args`.
std::vector<std::string> gui_command(const TempDir& dir, const std::vector<std::string>& args) {
  std::filesystem::create_directories(dir.path() / "web");
  dir.write("web/index.html", "<html></html>");
  std::vector<std::string> cmd{RACK_GUI_PATH, "--port", "0", "--web", (dir.path() / "web").string(), "--reports", ""};
  cmd.insert(cmd.end(), args.begin(), args.end());
  return cmd;
}

class HttpServerTest : public ::testing::Test {
 protected:
  HttpServerTest() : watchdog_(60s, "HttpServerTest") {
    std::filesystem::create_directories(dir_.path() / "web" / "assets");
    dir_.write("web/index.html", "<html>dashboard</html>");
    dir_.write("web/assets/app.js", "console.log(1);");
    dir_.write("secret.txt", "not for the browser");
    gui::ServerHandlers h;
    h.opened = [this](uint64_t c) { server_->send(c, "welcome"); };
    h.message = [this](uint64_t c, const std::string& text) {
      const std::lock_guard lock(mutex_);
      received_.push_back(text);
      server_->send(c, "echo:" + text);
    };
    h.closed = [this](uint64_t) { ++closed_; };
    h.refused = [this](uint64_t c, gui::FrameRefusal why, std::size_t bytes) {
      const std::lock_guard lock(mutex_);
      refused_.emplace_back(why, bytes);
      if (why == gui::FrameRefusal::kBinary) server_->send(c, "refused binary");
    };
    server_ = std::make_unique<gui::HttpServer>("127.0.0.1", 0, (dir_.path() / "web").string(), h);
    thread_ = std::thread([this] { server_->run(); });
  }
  ~HttpServerTest() override {
    server_->stop();
    thread_.join();
  }
  TempDir dir_;
  Watchdog watchdog_;
  std::unique_ptr<gui::HttpServer> server_;
  std::thread thread_;
  std::mutex mutex_;
  std::vector<std::string> received_;
  std::vector<std::pair<gui::FrameRefusal, std::size_t>> refused_;
  std::atomic<int> closed_{0};
};

TEST_F(HttpServerTest, ServesFilesBelowItsRootOnly) {
  const uint16_t port = server_->port();
  EXPECT_EQ(get(port, "/"), std::make_pair(200, std::string("<html>dashboard</html>")));
  EXPECT_EQ(get(port, "/assets/app.js?v=2").first, 200);
  EXPECT_EQ(get(port, "/../secret.txt").first, 400);
  EXPECT_EQ(get(port, "/assets/../../secret.txt").first, 400);
  EXPECT_EQ(get(port, "/assets\\..\\..\\secret.txt").first, 400);
  EXPECT_EQ(get(port, "/missing.js").first, 404);
  EXPECT_EQ(get(port, "/assets").first, 404) << "a directory is not a file";
}

TEST_F(HttpServerTest, WebSocketCarriesTextRefusesBinaryAndClosesOnOversizedMessages) {
  {
    WsClient c(server_->port());
    EXPECT_EQ(c.read(), "welcome");
    c.ws.text(true);
    c.ws.write(net::buffer(std::string("{\"op\":\"x\"}")));
    EXPECT_EQ(c.read(), "echo:{\"op\":\"x\"}");
    server_->send(0, "to everybody");
    EXPECT_EQ(c.read(), "to everybody");
  }
  {
    WsClient c(server_->port());
    EXPECT_EQ(c.read(), "welcome");
    c.ws.binary(true);
    c.ws.write(net::buffer(std::string("\x01\x02", 2)));
    EXPECT_EQ(c.read(), "refused binary") << "a binary message is refused, the connection stays";
    c.ws.text(true);
    c.ws.write(net::buffer(std::string("after")));
    EXPECT_EQ(c.read(), "echo:after");
  }
  {
    WsClient c(server_->port());
    EXPECT_EQ(c.read(), "welcome");
    c.ws.text(true);
    c.ws.write(net::buffer(std::string(gui::HttpServer::kMaxMessage + 1, 'x')));
    EXPECT_EQ(c.read(), "") << "an oversized message closes the connection";
    EXPECT_EQ(c.ws.reason().code, static_cast<uint16_t>(websocket::close_code::too_big));
  }
  // The server goes on serving the others.
  WsClient c(server_->port());
  EXPECT_EQ(c.read(), "welcome");
  const std::lock_guard lock(mutex_);
  ASSERT_EQ(received_.size(), 2u) << "only the valid text messages reached the message handler";
  ASSERT_EQ(refused_.size(), 2u);
  EXPECT_EQ(refused_[0], std::make_pair(gui::FrameRefusal::kBinary, std::size_t{2}));
  EXPECT_EQ(refused_[1].first, gui::FrameRefusal::kTooLarge);
  EXPECT_GT(refused_[1].second, gui::HttpServer::kMaxMessage);
}

// What one peer may hold of the server (ServerLimits): a client over max_clients is
// closed after its handshake with 1013 and the reason, counted, and the others are
// served on; there was no cap (a peer opening thousands of connections held thousands
// of sessions).
TEST(HttpServerLimitsTest, ClientsOverTheCapAreClosedWithTheReasonAndCounted) {
  TempDir dir;
  Watchdog watchdog(60s, "HttpServerLimitsTest");
  std::filesystem::create_directories(dir.path() / "web");
  gui::HttpServer* server_ptr = nullptr;
  gui::ServerHandlers h;
  h.opened = [&server_ptr](uint64_t c) { server_ptr->send(c, "welcome"); };
  gui::ServerLimits limits;
  limits.max_clients = 2;
  gui::HttpServer server("127.0.0.1", 0, (dir.path() / "web").string(), h, limits);
  server_ptr = &server;
  std::thread io([&server] { server.run(); });
  {
    WsClient a(server.port());
    WsClient b(server.port());
    EXPECT_EQ(a.read(), "welcome");
    EXPECT_EQ(b.read(), "welcome");
    WsClient c(server.port());
    EXPECT_EQ(c.read(), "") << "a third client is closed";
    EXPECT_EQ(c.ws.reason().code, static_cast<uint16_t>(websocket::close_code::try_again_later));
    EXPECT_NE(std::string(c.ws.reason().reason.c_str()).find("at most 2 clients"), std::string::npos)
        << c.ws.reason().reason.c_str();
    EXPECT_EQ(server.refused_clients(), 1u);
    server.send(0, "still served");
    EXPECT_EQ(a.read(), "still served");
    EXPECT_EQ(b.read(), "still served");
  }
  // Once they left, a new client is served (the server sees them go asynchronously).
  EXPECT_TRUE(eventually([&server] {
    WsClient d(server.port());
    return d.read() == "welcome";
  }));
  server.stop();
  io.join();
}

// A client that never reads: what waits for it is bounded in bytes, the oldest
// messages dropped (counted), the newest delivered once it reads. Before, 256 messages
// of any size waited (256 camera images: hundreds of MB per client).
TEST(HttpServerLimitsTest, AClientThatDoesNotReadHoldsABoundedQueue) {
  TempDir dir;
  Watchdog watchdog(60s, "HttpServerLimitsTest");
  std::filesystem::create_directories(dir.path() / "web");
  std::atomic<int> opened{0};
  gui::ServerHandlers h;
  h.opened = [&opened](uint64_t) { ++opened; };
  gui::ServerLimits limits;
  limits.max_queued_bytes = 2u << 20;  // two messages: the newest and "end" fit
  gui::HttpServer server("127.0.0.1", 0, (dir.path() / "web").string(), h, limits);
  std::thread io([&server] { server.run(); });
  WsClient c(server.port());
  ASSERT_TRUE(eventually([&opened] { return opened == 1; }));
  constexpr int kSent = 64;  // 64 MiB, far more than the socket buffers take
  for (int i = 0; i < kSent; ++i) server.send(0, std::to_string(i) + ":" + std::string(1u << 20, 'x'));
  server.send(0, "end");
  ASSERT_TRUE(eventually([&server] { return server.dropped_messages() >= kSent / 2; }))
      << server.dropped_messages() << " dropped";
  int received = 0;
  std::string last;
  for (std::string m = c.read(); !m.empty() && m != "end"; m = c.read()) {
    ++received;
    last = m.substr(0, m.find(':'));
  }
  EXPECT_LT(received, kSent / 2) << "the queue was not bounded";
  EXPECT_EQ(static_cast<uint64_t>(received) + server.dropped_messages(), static_cast<uint64_t>(kSent));
  EXPECT_EQ(last, std::to_string(kSent - 1)) << "the newest is delivered";
  server.stop();
  io.join();
}

// The real rack-gui (no robot on its bus): malformed messages get an error naming the
// problem and send nothing; a valid request to a component nobody runs fails with a
// reason.
TEST(RackGuiServerTest, RefusesMalformedMessagesAndReportsUnansweredRequests) {
  Watchdog watchdog(60s, "RackGuiServerTest");
  TempDir dir;
  LcmBus bus;
  Process gui(gui_command(dir, {"--lcm", bus.url(), "--timeout-ms", "300"}), dir.path(), "rack-gui");
  const uint16_t port = port_of(served_url(gui));
  ASSERT_NE(port, 0) << gui.err();

  WsClient c(port);
  EXPECT_EQ(c.read_type("hello")["version"], 1);
  c.ws.text(true);
  const auto refused = [&](const std::string& text, const std::string& expected) {
    c.ws.write(net::buffer(text));
    const auto j = c.read_type("error");
    ASSERT_TRUE(j.is_object()) << text;
    EXPECT_NE(j["error"].get<std::string>().find(expected), std::string::npos) << j.dump();
  };
  refused("{not json", "not JSON");
  refused(R"j({"op":"switch","component":"Chassis(0/0)","on":"yes","id":4})j", "key 'on': expected true or false");
  refused(R"j({"op":"joystick","system":0,"vx":1e9,"omega":0})j", "key 'vx'");
  refused(R"j({"op":"drive_fast","system":0})j", "unknown op 'drive_fast'");

  // A class by name (rack-gui links no class: names come from the descriptions) that
  // no component there describes: answered at once, nothing sent.
  c.ws.write(net::buffer(std::string(R"j({"op":"switch","component":"Chassis(7/0)","on":false,"id":8})j")));
  const auto unknown = c.read_type("result");
  ASSERT_TRUE(unknown.is_object());
  EXPECT_EQ(unknown["id"], 8);
  EXPECT_EQ(unknown["ok"], false);
  EXPECT_NE(unknown["text"].get<std::string>().find("Chassis(7/0): no component of that class"), std::string::npos)
      << unknown.dump();
  // By class id (the form of an address whose class is not described): sent, and
  // reported as not answered.
  c.ws.write(net::buffer(std::string(R"j({"op":"switch","component":"Class0x10(7/0)","on":false,"id":9})j")));
  const auto result = c.read_type("result");
  ASSERT_TRUE(result.is_object());
  EXPECT_EQ(result["id"], 9);
  EXPECT_EQ(result["ok"], false);
  EXPECT_NE(result["text"].get<std::string>().find("Class0x10(7/0): no reply to OFF"), std::string::npos)
      << result.dump();

  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();
  // The four refused messages sent nothing: the one request is the OFF.
  EXPECT_NE(gui.err().find("stopped; 1 request(s) sent, 1 not answered in time, 4 malformed client message(s)"),
            std::string::npos)
      << gui.err();
}

// Hostile browser input against the real rack-gui: each kind of bad message is
// refused with its reason, a flood of them neither ends nor stalls rack-gui (a valid
// request is still answered after it), and the counts by reason are in its final line.
TEST(RackGuiServerTest, HostileMessagesAreRefusedWithAReasonCountedAndNeverStallIt) {
  Watchdog watchdog(90s, "RackGuiServerTest.Hostile");
  TempDir dir;
  LcmBus bus;
  Process gui(gui_command(dir, {"--lcm", bus.url(), "--timeout-ms", "300"}), dir.path(), "rack-gui");
  const uint16_t port = port_of(served_url(gui));
  ASSERT_NE(port, 0) << gui.err();

  WsClient c(port);
  EXPECT_EQ(c.read_type("hello")["version"], 1);
  const auto refused = [&](const std::string& text, const std::string& reason, const std::string& expected) {
    c.ws.text(true);
    c.ws.write(net::buffer(text));
    const auto j = c.read_type("error");
    ASSERT_TRUE(j.is_object()) << text.substr(0, 100);
    EXPECT_EQ(j.value("reason", ""), reason) << j.dump();
    EXPECT_NE(j["error"].get<std::string>().find(expected), std::string::npos) << j.dump();
    EXPECT_LT(j.dump().size(), 1200u) << "a refusal quotes the client's text cut short";
  };
  refused("{\"op\":\"all_off\",\"system\":0,\"system\":1}", "duplicate_key", "key 'system' given twice");
  refused(std::string(5000, '[') + std::string(5000, ']'), "too_deep", "nested deeper than 8");
  refused(R"j({"op":"all_off","system":18446744073709551615})j", "bad_value", "not a robot's system number");
  refused(R"j({"op":"all_off","system":0,"id":18446744073709551615})j", "bad_value", "key 'id'");
  refused(R"j({"op":"set_pose","system":0,"x":1e400,"y":0,"phi":0})j", "not_json", "number overflow");
  refused("{\"op\":\"" + std::string(40000, 'A') + "\"}", "bad_op", "unknown op 'AAAA");
  refused(R"j({"op":"joystick","system":0,"vx":0.1})j", "bad_key", "missing key 'omega'");
  c.ws.binary(true);
  c.ws.write(net::buffer(std::string("\x00\x01\x02", 3)));
  EXPECT_EQ(c.read_type("error").value("reason", ""), "binary");

  // A flood: 2000 malformed messages, 100 at a time (as fast as the socket takes
  // them; the answers are read after each 100, since a client that does not read loses
  // its oldest answers beyond HttpServer::kMaxQueue).
  c.ws.text(true);
  for (int batch = 0; batch < 20; ++batch) {
    for (int i = 0; i < 100; ++i) c.ws.write(net::buffer("{\"op\":" + std::to_string(i)));
    for (int i = 0; i < 100; ++i) {
      const auto j = c.read_type("error");
      ASSERT_TRUE(j.is_object()) << "batch " << batch << ", answer " << i;
    }
  }
  // Still serving: a valid request is answered (no robot: it fails with a reason).
  c.ws.write(net::buffer(std::string(R"j({"op":"switch","component":"Chassis(7/0)","on":false,"id":3})j")));
  const auto result = c.read_type("result");
  ASSERT_TRUE(result.is_object());
  EXPECT_EQ(result["id"], 3);
  // An oversized message ends only that connection (1009); a new one is served.
  {
    WsClient big(port);
    EXPECT_EQ(big.read_type("hello")["version"], 1);
    big.ws.text(true);
    big.ws.write(net::buffer(std::string(gui::HttpServer::kMaxMessage + 1, ' ')));
    EXPECT_EQ(big.read_type("error"), nullptr);
    EXPECT_EQ(big.ws.reason().code, static_cast<uint16_t>(websocket::close_code::too_big));
  }
  // Not UTF-8 in a text message: that connection ends (1007), as RFC 6455 says.
  {
    WsClient bad(port);
    EXPECT_EQ(bad.read_type("hello")["version"], 1);
    bad.ws.text(true);
    bad.ws.write(net::buffer(std::string("{\"op\":\"all_off\",\"system\":0,\"x\":\"\xff\xfe\"}")));
    EXPECT_EQ(bad.read_type("error"), nullptr);
    EXPECT_EQ(bad.ws.reason().code, static_cast<uint16_t>(websocket::close_code::bad_payload));
  }
  WsClient after(port);
  EXPECT_EQ(after.read_type("hello")["version"], 1);

  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();
  const std::string out = gui.err();
  EXPECT_NE(out.find("2010 malformed client message(s) (too_large 1, not_json 2002, too_deep 1, duplicate_key 1, "
                     "bad_op 1, bad_key 1, bad_value 2, binary 1)"),
            std::string::npos)
      << out.substr(out.size() > 2000 ? out.size() - 2000 : 0);
  EXPECT_NE(out.find("refused (duplicate_key)"), std::string::npos) << "logged with its reason";
  EXPECT_LT(std::count(out.begin(), out.end(), '\n'), 100) << "the log of refusals is rate-limited";
}

// Authenticated links (issue 11): rack-gui takes the host file's network and key file
// (--host-file) and sees the keyed host's components; without the key it sees nothing.
TEST(RackGuiServerTest, SeesAKeyedHostOnlyWithItsKeyFile) {
  Watchdog watchdog(90s, "RackGuiServerTest.Keyed");
  TempDir dir;
  LcmBus bus;
  const auto key = dir.write("link.key", std::string(64, 'b') + "\n");
  std::filesystem::permissions(key, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  const auto host = dir.write("keyed.yaml",
                              "host: keyed\nsystem: 0\nheap_prefault_mib: 0\ntims:\n  announce_ms: 300\n"
                              "  networks:\n    - {name: robot, url: \"" +
                                  bus.url() + "\", scope: robot, key_file: \"" + key.string() +
                                  "\"}\n"
                                  "components:\n  - name: generator\n    class: Generator\n    instance: 0\n"
                                  "    autostart: true\n    data_task: {priority: 60, period_ms: 10}\n");
  Process rackd({RACK_RACKD_PATH, host.string()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();

  // The components rack-gui reports within `limit` (names), from one rack-gui run.
  const auto components_seen = [&](std::vector<std::string> args, std::chrono::seconds limit) {
    args.insert(args.begin(), {"--poll-ms", "100"});
    Process gui(gui_command(dir, args), dir.path(), "rack-gui");
    std::vector<std::string> names;
    const uint16_t port = port_of(served_url(gui));
    if (port == 0) {
      ADD_FAILURE() << gui.err();
      return names;
    }
    WsClient c(port);
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (names.empty() && std::chrono::steady_clock::now() < deadline) {
      const auto j = c.read_type("components");
      if (!j.is_object()) break;
      for (const auto& robot : j["robots"]) {
        for (const auto& h : robot["hosts"]) {
          for (const auto& comp : h["components"]) names.push_back(comp.value("name", ""));
        }
      }
    }
    gui.signal(SIGTERM);
    EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();
    return names;
  };
  const auto with_key = components_seen({"--host-file", host.string()}, 20s);
  ASSERT_EQ(with_key.size(), 1u);
  EXPECT_EQ(with_key[0], "generator");
  EXPECT_TRUE(components_seen({"--lcm", bus.url()}, 4s).empty()) << "without the key the keyed host is invisible";

  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(20s), std::optional<int>(0)) << rackd.err();
}

}  // namespace
}  // namespace rack::test

namespace rack::test {
namespace {

// Classes describe themselves (issue 19): rack-gui, built with no plug-in class,
// sends the data of one (the Counter plug-in, class 0x91) with its field names and
// its class name, from the class's description (GET_CLASS).
TEST(RackGuiServerTest, PluginClassDataHasItsFieldNames) {
  Watchdog watchdog(60s, "RackGuiServerTest.PluginClass");
  TempDir dir;
  LcmBus bus;
  const auto host = dir.write("counter.yaml", std::string("host: gui-describe\nsystem: 2\nheap_prefault_mib: 0\n") +
                                                  "plugins: [" + RACK_COUNTER_PLUGIN_PATH +
                                                  "]\ncomponents:\n"
                                                  "  - name: counter\n    class: Counter\n    instance: 0\n"
                                                  "    autostart: true\n    data_task: {period_ms: 20}\n"
                                                  "    params: {label: hello}\n");
  Process rackd({RACK_RACKD_PATH, host.string(), "--lcm", bus.url()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  Process gui(gui_command(dir, {"--lcm", bus.url(), "--poll-ms", "100"}), dir.path(), "rack-gui");
  const uint16_t port = port_of(served_url(gui));
  ASSERT_NE(port, 0) << gui.err();
  WsClient c(port);
  nlohmann::json data;
  for (int i = 0; i < 50 && !data.is_object(); ++i) {
    const auto j = c.read_type("data");
    ASSERT_TRUE(j.is_object()) << "no data message: " << gui.err();
    // Its address with its class by the described name (the dashboard sends it back
    // in requests, and rack-gui finds the component by that name).
    if (j.value("component", "") == "Counter(2/0)") data = j;
  }
  ASSERT_TRUE(data.is_object()) << gui.err();
  EXPECT_EQ(data["class"], "Counter") << data.dump();
  ASSERT_TRUE(data["data"].is_object()) << data.dump();
  EXPECT_EQ(data["data"]["label"], "hello") << data.dump();
  EXPECT_TRUE(data["data"]["count"].is_number()) << data.dump();
  EXPECT_TRUE(data["data"]["rate"].is_number()) << data.dump();
  // Requests by that address: its parameters, and switching it off.
  c.send({{"op", "get_params"}, {"component", "Counter(2/0)"}, {"id", 1}});
  const auto params = c.read_type("params");
  ASSERT_TRUE(params.is_object()) << gui.err();
  EXPECT_EQ(params["component"], "Counter(2/0)") << params.dump();
  c.send({{"op", "switch"}, {"component", "Counter(2/0)"}, {"on", false}, {"id", 2}});
  nlohmann::json off;
  for (int i = 0; i < 20 && !(off.is_object() && off.value("id", 0) == 2); ++i) off = c.read_type("result");
  ASSERT_TRUE(off.is_object()) << gui.err();
  EXPECT_EQ(off["ok"], true) << off.dump();
  EXPECT_EQ(off["text"], "Counter(2/0) off") << off.dump();
  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();
}

// The dashboard's parameter editor (op set_param) takes a parameter's former name as
// the host file does (docs/parameters.md): the new one is set, and the result says so.
TEST(RackGuiServerTest, SetParamByAFormerNameSetsTheNewOneWithAWarning) {
  Watchdog watchdog(60s, "RackGuiServerTest.FormerName");
  TempDir dir;
  LcmBus bus;
  const auto host = dir.write("monitor.yaml",
                              "host: gui-former\nsystem: 3\nheap_prefault_mib: 0\ncomponents:\n"
                              "  - name: gen\n    class: Generator\n    instance: 0\n"
                              "    data_task: {period_ms: 10}\n"
                              "  - name: mon\n    class: Monitor\n    instance: 0\n"
                              "    autostart: true\n    params: {source: gen}\n");
  Process rackd({RACK_RACKD_PATH, host.string(), "--lcm", bus.url()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  Process gui(gui_command(dir, {"--lcm", bus.url(), "--poll-ms", "100"}), dir.path(), "rack-gui");
  const uint16_t port = port_of(served_url(gui));
  ASSERT_NE(port, 0) << gui.err();
  WsClient c(port);
  bool described = false;  // the monitor's data came with its class's name: rack-gui knows it
  for (int i = 0; i < 100 && !described; ++i) {
    const auto j = c.read_type("data");
    ASSERT_TRUE(j.is_object()) << "no data message: " << gui.err();
    described = j.value("component", "") == "Monitor(3/0)";
  }
  ASSERT_TRUE(described) << gui.err();
  c.send({{"op", "set_param"}, {"component", "Monitor(3/0)"}, {"name", "period_ms"}, {"value", 50}, {"id", 7}});
  nlohmann::json set;
  for (int i = 0; i < 20 && !(set.is_object() && set.value("id", 0) == 7); ++i) set = c.read_type("result");
  ASSERT_TRUE(set.is_object()) << gui.err();
  EXPECT_EQ(set["ok"], true) << set.dump();
  const std::string text = set.value("text", "");
  EXPECT_NE(text.find("Monitor(3/0): source_period_ms = 50"), std::string::npos) << text;
  EXPECT_NE(text.find("warning: parameter 'period_ms' is now 'source_period_ms'"), std::string::npos) << text;
  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();
}

}  // namespace
}  // namespace rack::test
