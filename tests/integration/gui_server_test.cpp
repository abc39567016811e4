// rack-gui's server without a browser (so these paths are covered where Chromium is
// missing): static files and the WebSocket of HttpServer with a Boost.Beast client,
// and the real rack-gui refusing malformed WebSocket messages on a private LCM bus.
#include <gtest/gtest.h>
#include <signal.h>

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "http_server.h"
#include "process.h"

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

struct WsClient {
  net::io_context ioc;
  websocket::stream<beast::tcp_stream> ws{ioc};
  explicit WsClient(uint16_t port) {
    beast::get_lowest_layer(ws).connect(tcp::endpoint(net::ip::make_address("127.0.0.1"), port));
    beast::get_lowest_layer(ws).expires_after(10s);
    ws.handshake("127.0.0.1", "/ws");
  }
  // The next text message; "" when the connection closed (or timed out).
  std::string read() {
    beast::flat_buffer buf;
    beast::error_code ec;
    ws.read(buf, ec);
    return ec ? "" : beast::buffers_to_string(buf.data());
  }
  // The next message of `type`, skipping the periodic ones.
  nlohmann::json read_type(const std::string& type) {
    for (int i = 0; i < 200; ++i) {
      const std::string m = read();
      if (m.empty()) return nullptr;
      auto j = nlohmann::json::parse(m, nullptr, false);
      if (!j.is_discarded() && j.value("type", "") == type) return j;
    }
    return nullptr;
  }
};

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

TEST_F(HttpServerTest, WebSocketCarriesTextAndClosesOnBinaryOrOversizedMessages) {
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
    EXPECT_EQ(c.read(), "") << "a binary message closes the connection";
  }
  {
    WsClient c(server_->port());
    EXPECT_EQ(c.read(), "welcome");
    c.ws.text(true);
    c.ws.write(net::buffer(std::string(gui::HttpServer::kMaxMessage + 1, 'x')));
    EXPECT_EQ(c.read(), "") << "an oversized message closes the connection";
  }
  const std::lock_guard lock(mutex_);
  ASSERT_EQ(received_.size(), 1u) << "only the valid text message reached the handler";
}

// The real rack-gui (no robot on its bus): malformed messages get an error naming the
// problem and send nothing; a valid request to a component nobody runs fails with a
// reason.
TEST(RackGuiServerTest, RefusesMalformedMessagesAndReportsUnansweredRequests) {
  Watchdog watchdog(60s, "RackGuiServerTest");
  TempDir dir;
  LcmBus bus;
  std::filesystem::create_directories(dir.path() / "web");
  dir.write("web/index.html", "<html></html>");
  Process gui({RACK_GUI_PATH, "--port", "0", "--lcm", bus.url(), "--web", (dir.path() / "web").string(), "--reports",
               "", "--timeout-ms", "300"},
              dir.path(), "rack-gui");
  ASSERT_TRUE(gui.wait_for_stderr("rack-gui: serving http://", 15s)) << gui.err();
  const std::string err = gui.err();
  const auto colon = err.find(':', err.find("http://127.0.0.1") + 10);
  const auto port = static_cast<uint16_t>(std::stoi(err.substr(colon + 1)));

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

  c.ws.write(net::buffer(std::string(R"j({"op":"switch","component":"Chassis(7/0)","on":false,"id":9})j")));
  const auto result = c.read_type("result");
  ASSERT_TRUE(result.is_object());
  EXPECT_EQ(result["id"], 9);
  EXPECT_EQ(result["ok"], false);
  EXPECT_NE(result["text"].get<std::string>().find("Chassis(7/0)"), std::string::npos) << result.dump();

  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(10s), std::optional<int>(0)) << gui.err();
  // The four refused messages sent nothing: the one request is the OFF.
  EXPECT_NE(gui.err().find("stopped; 1 request(s) sent, 1 not answered in time, 4 malformed client message(s)"),
            std::string::npos)
      << gui.err();
}

// Authenticated links (issue 11): rack-gui takes the host file's network and key file
// (--host-file) and sees the keyed host's components; without the key it sees nothing.
TEST(RackGuiServerTest, SeesAKeyedHostOnlyWithItsKeyFile) {
  Watchdog watchdog(90s, "RackGuiServerTest.Keyed");
  TempDir dir;
  LcmBus bus;
  std::filesystem::create_directories(dir.path() / "web");
  dir.write("web/index.html", "<html></html>");
  const auto key = dir.write("link.key", std::string(64, 'b') + "\n");
  std::filesystem::permissions(key, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  const auto host = dir.write("keyed.yaml",
                              "host: keyed\nsystem: 0\nheap_prefault_mib: 0\ntims:\n  announce_ms: 300\n"
                              "  networks:\n    - {name: robot, url: \"" + bus.url() +
                                  "\", scope: robot, key_file: \"" + key.string() + "\"}\n"
                              "components:\n  - name: generator\n    class: Generator\n    instance: 0\n"
                              "    autostart: true\n    data_task: {priority: 60, period_ms: 10}\n");
  Process rackd({RACK_RACKD_PATH, host.string()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();

  // The components rack-gui reports within `limit` (names), from one rack-gui run.
  const auto components_seen = [&](std::vector<std::string> args, std::chrono::seconds limit) {
    std::vector<std::string> cmd{RACK_GUI_PATH, "--port", "0", "--web", (dir.path() / "web").string(), "--reports",
                                 "", "--poll-ms", "100"};
    cmd.insert(cmd.end(), args.begin(), args.end());
    Process gui(cmd, dir.path(), "rack-gui");
    std::vector<std::string> names;
    if (!gui.wait_for_stderr("rack-gui: serving http://", 15s)) {
      ADD_FAILURE() << gui.err();
      return names;
    }
    const std::string err = gui.err();
    const auto colon = err.find(':', err.find("http://127.0.0.1") + 10);
    WsClient c(static_cast<uint16_t>(std::stoi(err.substr(colon + 1))));
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
