// A WebSocket client of rack-gui for the tests (Boost.Beast, blocking, with a
// timeout): what a browser's page receives, without a browser. Used by
// gui_server_test.cpp and, against the installed rack-gui, sdk_out_of_tree_test.cpp.
#pragma once

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/websocket.hpp>

#include <chrono>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

namespace rack::test {

struct WsClient {
  boost::asio::io_context ioc;
  boost::beast::websocket::stream<boost::beast::tcp_stream> ws{ioc};
  explicit WsClient(uint16_t port) {
    using boost::asio::ip::tcp;
    boost::beast::get_lowest_layer(ws).connect(tcp::endpoint(boost::asio::ip::make_address("127.0.0.1"), port));
    boost::beast::get_lowest_layer(ws).expires_after(std::chrono::seconds(10));
    ws.handshake("127.0.0.1", "/ws");
  }
  // The next text message; "" when the connection closed (or timed out).
  std::string read() {
    boost::beast::flat_buffer buf;
    boost::beast::error_code ec;
    ws.read(buf, ec);
    return ec ? "" : boost::beast::buffers_to_string(buf.data());
  }
  // The next message of `type`, skipping the periodic ones (null when none came).
  nlohmann::json read_type(const std::string& type) {
    for (int i = 0; i < 200; ++i) {
      const std::string m = read();
      if (m.empty()) return nullptr;
      auto j = nlohmann::json::parse(m, nullptr, false);
      if (!j.is_discarded() && j.value("type", "") == type) return j;
    }
    return nullptr;
  }
  void send(const nlohmann::json& request) {
    boost::beast::get_lowest_layer(ws).expires_after(std::chrono::seconds(10));
    ws.text(true);
    ws.write(boost::asio::buffer(request.dump()));
  }
};

// The port of the rack-gui whose stderr is `err` ("rack-gui: serving http://127.0.0.1:PORT/").
inline uint16_t served_port(const std::string& err) {
  const auto colon = err.find(':', err.find("http://127.0.0.1") + 10);
  return static_cast<uint16_t>(std::stoi(err.substr(colon + 1)));
}

}  // namespace rack::test
