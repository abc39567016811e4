#include "http_server.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <optional>
#include <utility>

#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>

#include <cstdio>
#include <deque>
#include <filesystem>
#include <map>
#include <stdexcept>

namespace rack::gui {

namespace beast = boost::beast;
namespace http = beast::http;
namespace websocket = beast::websocket;
namespace net = boost::asio;
using tcp = net::ip::tcp;

namespace {

std::string mime_type(const std::string& path) {
  const auto ext = std::filesystem::path(path).extension().string();
  if (ext == ".html") return "text/html; charset=utf-8";
  if (ext == ".js" || ext == ".mjs") return "text/javascript; charset=utf-8";
  if (ext == ".css") return "text/css; charset=utf-8";
  if (ext == ".json") return "application/json";
  if (ext == ".svg") return "image/svg+xml";
  if (ext == ".png") return "image/png";
  if (ext == ".ico") return "image/x-icon";
  if (ext == ".woff2") return "font/woff2";
  return "application/octet-stream";
}

}  // namespace

struct HttpServer::Impl : std::enable_shared_from_this<HttpServer::Impl> {
  class WsSession;

  Impl(const std::string& address, uint16_t port, std::string root, ServerHandlers h, ServerLimits l)
      : web_root(std::move(root)), handlers(std::move(h)), limits(l), acceptor(ioc) {
    beast::error_code ec;
    const auto addr = net::ip::make_address(address, ec);
    if (ec) throw std::runtime_error("'" + address + "' is not an IP address: " + ec.message());
    const tcp::endpoint ep(addr, port);
    acceptor.open(ep.protocol(), ec);
    if (!ec) acceptor.set_option(net::socket_base::reuse_address(true), ec);
    if (!ec) acceptor.bind(ep, ec);
    if (!ec) acceptor.listen(net::socket_base::max_listen_connections, ec);
    if (ec) {
      // What to do about the two a user meets (another program on the port, a port
      // below 1024), beside the system's text.
      std::string hint;
      if (ec == net::error::address_in_use) {
        hint =
            " (another program, maybe another rack-gui, listens there: --port PORT for another, --port 0 for "
            "any free one)";
      } else if (ec == net::error::access_denied) {
        hint = " (a port below 1024 needs root or CAP_NET_BIND_SERVICE: --port 8080, or any above 1023)";
      } else if (ec == boost::system::errc::address_not_available) {
        hint = " (not an address of this machine: --address 127.0.0.1, or 0.0.0.0 for every interface)";
      }
      throw std::runtime_error("cannot listen on " + address + ":" + std::to_string(port) + ": " + ec.message() + hint);
    }
  }

  void accept() {
    acceptor.async_accept(net::make_strand(ioc), [self = shared_from_this()](beast::error_code ec, tcp::socket s) {
      if (!ec) {
        self->accept_failing = false;
        std::make_shared<HttpSession>(self, std::move(s))->start();
      } else if (self->acceptor.is_open() && ec != net::error::operation_aborted) {
        // Out of file descriptors (EMFILE: a client holding many connections) accept
        // fails at once, again and again: it spun a core, silently. Said once; tried
        // again every 100 ms until it works.
        if (!self->accept_failing) {
          std::fprintf(stderr, "rack-gui: cannot accept connections: %s (trying again every 100 ms)\n",
                       ec.message().c_str());
        }
        self->accept_failing = true;
        self->accept_retry.expires_after(std::chrono::milliseconds(100));
        self->accept_retry.async_wait([self](beast::error_code) {
          if (self->acceptor.is_open()) self->accept();
        });
        return;
      }
      if (self->acceptor.is_open()) self->accept();
    });
  }

  // One HTTP connection; hands itself to a WsSession on an upgrade to /ws.
  class HttpSession : public std::enable_shared_from_this<HttpSession> {
   public:
    HttpSession(std::shared_ptr<Impl> server, tcp::socket socket)
        : server_(std::move(server)), stream_(std::move(socket)) {}
    void start() { read(); }

   private:
    void read() {
      parser_.emplace();
      parser_->body_limit(16 * 1024);  // the dashboard only GETs
      stream_.expires_after(std::chrono::seconds(30));
      http::async_read(stream_, buffer_, *parser_, [self = shared_from_this()](beast::error_code ec, std::size_t) {
        if (ec) return;
        self->on_request(self->parser_->release());
      });
    }

    void on_request(http::request<http::string_body> req) {
      if (websocket::is_upgrade(req)) {
        if (req.target() != "/ws") {
          reply(req, http::status::not_found, "no WebSocket at this path; the dashboard's is /ws\n", "text/plain");
          return;
        }
        stream_.expires_never();
        std::make_shared<WsSession>(server_, stream_.release_socket())->start(std::move(req));
        return;
      }
      if (req.method() != http::verb::get && req.method() != http::verb::head) {
        reply(req, http::status::method_not_allowed, "only GET\n", "text/plain");
        return;
      }
      std::string target(req.target());
      if (const auto q = target.find('?'); q != std::string::npos) target.resize(q);
      if (target.empty() || target[0] != '/' || target.find("..") != std::string::npos ||
          target.find('\\') != std::string::npos || target.find('\0') != std::string::npos) {
        reply(req, http::status::bad_request, "bad path\n", "text/plain");
        return;
      }
      if (target.back() == '/') target += "index.html";
      const std::string path = server_->web_root + target;
      std::error_code fec;
      if (!std::filesystem::is_regular_file(path, fec)) {
        reply(req, http::status::not_found, "not found: " + target + "\n", "text/plain");
        return;
      }
      http::file_body::value_type body;
      beast::error_code ec;
      body.open(path.c_str(), beast::file_mode::scan, ec);
      if (ec) {
        reply(req, http::status::internal_server_error, "cannot read " + target + ": " + ec.message() + "\n",
              "text/plain");
        return;
      }
      auto res = std::make_shared<http::response<http::file_body>>(
          std::piecewise_construct, std::make_tuple(std::move(body)), std::make_tuple(http::status::ok, req.version()));
      res->set(http::field::server, "rack-gui");
      res->set(http::field::content_type, mime_type(path));
      res->set(http::field::cache_control, "no-cache");
      res->keep_alive(req.keep_alive());
      res->prepare_payload();
      http::async_write(stream_, *res, [self = shared_from_this(), res](beast::error_code wec, std::size_t) {
        if (!wec && res->keep_alive()) self->read();
      });
    }

    void reply(const http::request<http::string_body>& req, http::status status, const std::string& text,
               const char* type) {
      auto res = std::make_shared<http::response<http::string_body>>(status, req.version());
      res->set(http::field::server, "rack-gui");
      res->set(http::field::content_type, type);
      res->keep_alive(req.keep_alive());
      res->body() = text;
      res->prepare_payload();
      http::async_write(stream_, *res, [self = shared_from_this(), res](beast::error_code ec, std::size_t) {
        if (!ec && res->keep_alive()) self->read();
      });
    }

    std::shared_ptr<Impl> server_;
    beast::tcp_stream stream_;
    beast::flat_buffer buffer_;
    std::optional<http::request_parser<http::string_body>> parser_;
  };

  class WsSession : public std::enable_shared_from_this<WsSession> {
   public:
    WsSession(std::shared_ptr<Impl> server, tcp::socket socket) : server_(std::move(server)), ws_(std::move(socket)) {}

    void start(http::request<http::string_body> req) {
      ws_.set_option(websocket::stream_base::timeout::suggested(beast::role_type::server));
      ws_.read_message_max(kMaxMessage);
      ws_.async_accept(req, [self = shared_from_this()](beast::error_code ec) {
        if (ec) return;
        if (self->server_->sessions.size() >= self->server_->limits.max_clients) {
          self->refuse_full();
          return;
        }
        self->id_ = ++self->server_->next_client;
        self->server_->sessions[self->id_] = self;
        if (self->server_->handlers.opened) self->server_->handlers.opened(self->id_);
        self->read();
      });
    }

    // I/O thread only. The oldest waiting messages make room (never the one being
    // written: write() took it off the queue).
    void send(std::shared_ptr<const std::string> m) {
      if (closed_) return;
      while (!queue_.empty() &&
             (queue_.size() >= kMaxQueue || queued_bytes_ + m->size() > server_->limits.max_queued_bytes)) {
        queued_bytes_ -= queue_.front()->size();
        queue_.pop_front();
        ++dropped_;
        server_->dropped_messages.fetch_add(1, std::memory_order_relaxed);  // relaxed: a statistic
      }
      queued_bytes_ += m->size();
      queue_.push_back(std::move(m));
      if (!writing_) write();
    }

   private:
    // One client more than limits.max_clients: closed at once with the reason, counted.
    void refuse_full() {
      closed_ = true;
      const std::size_t max = server_->limits.max_clients;
      const uint64_t n = server_->refused_clients.fetch_add(1, std::memory_order_relaxed) + 1;  // a statistic
      if (n == 1 || n % 100 == 0) {
        std::fprintf(stderr,
                     "rack-gui: WebSocket client refused: %zu connected, the most --max-clients allows (%llu "
                     "refused so far)\n",
                     max, static_cast<unsigned long long>(n));
      }
      const std::string why = "rack-gui serves at most " + std::to_string(max) + " clients at once (--max-clients)";
      ws_.async_close(websocket::close_reason(websocket::close_code::try_again_later, why),
                      [self = shared_from_this()](beast::error_code) {});
    }

    void read() {
      ws_.async_read(buffer_, [self = shared_from_this()](beast::error_code ec, std::size_t bytes) {
        const auto& h = self->server_->handlers;
        if (ec) {
          // Beast has failed the connection already (1009 over read_message_max, 1007
          // for a text message that is not UTF-8).
          if (ec == websocket::error::message_too_big && h.refused) {
            self->call([&] { h.refused(self->id_, FrameRefusal::kTooLarge, std::max(bytes, kMaxMessage + 1)); });
          } else if (ec == websocket::error::bad_frame_payload && h.refused) {
            self->call([&] { h.refused(self->id_, FrameRefusal::kNotUtf8, bytes); });
          }
          self->close();
          return;
        }
        if (!self->ws_.got_text()) {
          self->buffer_.consume(self->buffer_.size());
          if (h.refused) self->call([&] { h.refused(self->id_, FrameRefusal::kBinary, bytes); });
          self->read();
          return;
        }
        const std::string text = beast::buffers_to_string(self->buffer_.data());
        self->buffer_.consume(self->buffer_.size());
        if (h.message) self->call([&] { h.message(self->id_, text); });
        self->read();
      });
    }

    // A handler's exception would end the I/O loop (and rack-gui): reported, and the
    // server goes on.
    template <typename Fn>
    void call(Fn fn) noexcept {
      try {
        fn();
      } catch (const std::exception& e) {
        std::fprintf(stderr, "rack-gui: client %llu: message handler failed: %s\n",
                     static_cast<unsigned long long>(id_), e.what());
      } catch (...) {
        std::fprintf(stderr, "rack-gui: client %llu: message handler failed\n", static_cast<unsigned long long>(id_));
      }
    }

    void write() {
      if (queue_.empty() || closed_) {
        writing_ = false;
        return;
      }
      writing_ = true;
      // The message being written stays alive in `current_` (the queue may drop it).
      current_ = queue_.front();
      queue_.pop_front();
      queued_bytes_ -= current_->size();
      ws_.text(true);
      ws_.async_write(net::buffer(*current_), [self = shared_from_this()](beast::error_code ec, std::size_t) {
        if (ec) {
          self->close();
          return;
        }
        self->write();
      });
    }

    void close() {
      if (closed_) return;
      closed_ = true;
      server_->sessions.erase(id_);
      if (id_ != 0 && server_->handlers.closed) server_->handlers.closed(id_);
      if (dropped_ > 0) {
        std::fprintf(stderr, "rack-gui: client %llu: %llu message(s) dropped (browser too slow)\n",
                     static_cast<unsigned long long>(id_), static_cast<unsigned long long>(dropped_));
      }
    }

    std::shared_ptr<Impl> server_;
    websocket::stream<beast::tcp_stream> ws_;
    beast::flat_buffer buffer_;
    std::deque<std::shared_ptr<const std::string>> queue_;
    std::shared_ptr<const std::string> current_;
    bool writing_ = false;
    bool closed_ = false;
    uint64_t id_ = 0;
    uint64_t dropped_ = 0;
    std::size_t queued_bytes_ = 0;  // of the messages in queue_
  };

  net::io_context ioc{1};
  std::string web_root;
  ServerHandlers handlers;
  ServerLimits limits;
  std::atomic<uint64_t> refused_clients{0};
  std::atomic<uint64_t> dropped_messages{0};
  tcp::acceptor acceptor;
  net::steady_timer accept_retry{ioc};  // accept() after a failed accept (EMFILE)
  bool accept_failing = false;          // said so already (the acceptor's handlers run one at a time)
  uint64_t next_client = 0;
  std::map<uint64_t, std::weak_ptr<WsSession>> sessions;  // I/O thread only
};

HttpServer::HttpServer(const std::string& address, uint16_t port, std::string web_root, ServerHandlers handlers,
                       ServerLimits limits)
    : impl_(std::make_shared<Impl>(address, port, std::move(web_root), std::move(handlers), limits)) {}

uint64_t HttpServer::refused_clients() const { return impl_->refused_clients.load(std::memory_order_relaxed); }
uint64_t HttpServer::dropped_messages() const { return impl_->dropped_messages.load(std::memory_order_relaxed); }

HttpServer::~HttpServer() { stop(); }

uint16_t HttpServer::port() const { return impl_->acceptor.local_endpoint().port(); }

void HttpServer::run() {
  impl_->accept();
  impl_->ioc.run();
}

void HttpServer::stop() { impl_->ioc.stop(); }

void HttpServer::send(uint64_t client, std::string message) {
  auto m = std::make_shared<const std::string>(std::move(message));
  net::post(impl_->ioc, [impl = impl_, client, m] {
    if (client != 0) {
      const auto it = impl->sessions.find(client);
      if (it != impl->sessions.end()) {
        if (auto s = it->second.lock()) s->send(m);
      }
      return;
    }
    for (auto& [id, weak] : impl->sessions) {
      if (auto s = weak.lock()) s->send(m);
    }
  });
}

}  // namespace rack::gui
