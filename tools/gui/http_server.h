// rack-gui's HTTP and WebSocket server (Boost.Beast, one I/O thread): serves the
// built dashboard from a directory and speaks the JSON protocol on /ws.
//
// Static files: only regular files below the web root; paths with "..", NUL or
// backslashes are refused (400), anything else missing is 404. The dashboard loads
// nothing from elsewhere.
//
// WebSocket: text messages only, at most kMaxMessage bytes. A binary message is
// refused (handlers.refused, which answers it; the connection stays); a larger one ends
// the connection with close code 1009 "message too big" (RFC 6455: the rest of it
// cannot be skipped), a text message that is not UTF-8 with 1007 (RFC 6455 8.1), both
// reported through handlers.refused too. Neither stalls the
// server or the other clients. Outgoing messages queue per client;
// a client that does not keep up (or never reads) loses the oldest queued messages
// beyond kMaxQueue messages or ServerLimits::max_queued_bytes (counted), so a slow
// browser never stalls the others or grows memory. At most ServerLimits::max_clients
// WebSocket clients are served at once: one more is closed after its handshake with
// 1013 "try again later" and the reason (RFC 6455 7.4.1), counted, the first and
// every 100th said on stderr.
//
// Not RT code (a tool). Thread-safety: send() may be called from any thread (it
// posts to the I/O thread); everything else runs on the I/O thread.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>

namespace rack::gui {

enum class FrameRefusal : uint8_t {
  kBinary,    // a binary message (the protocol is JSON text); the client stays connected
  kTooLarge,  // over kMaxMessage; the connection was closed (1009)
  kNotUtf8,   // a text message that is not UTF-8; the connection was closed (1007)
};

struct ServerHandlers {
  std::function<void(uint64_t client)> opened;
  std::function<void(uint64_t client, const std::string& text)> message;
  std::function<void(uint64_t client)> closed;
  // A message refused by the server itself; `bytes`: its size as far as known.
  std::function<void(uint64_t client, FrameRefusal why, std::size_t bytes)> refused;
};

// What one peer may hold of rack-gui (rack-gui --max-clients sets the first).
struct ServerLimits {
  std::size_t max_clients = 64;              // WebSocket clients served at once
  std::size_t max_queued_bytes = 16u << 20;  // per client: output waiting to be sent (a
                                             // larger message alone still goes)
};

class HttpServer {
 public:
  static constexpr std::size_t kMaxMessage = 64 * 1024;
  static constexpr std::size_t kMaxQueue = 256;

  // Binds address:port (port 0: any free port). Throws std::runtime_error with the
  // address on failure (in use, not an address of this machine).
  HttpServer(const std::string& address, uint16_t port, std::string web_root, ServerHandlers handlers,
             ServerLimits limits = {});
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  [[nodiscard]] uint16_t port() const;
  // Runs the I/O loop until stop() (from any thread, or a signal handler's thread).
  void run();
  void stop();
  // To one client, or to every client when `client` is 0. Any thread.
  void send(uint64_t client, std::string message);
  // WebSocket clients refused (max_clients were connected), and messages dropped for
  // clients that did not keep up. Any thread.
  [[nodiscard]] uint64_t refused_clients() const;
  [[nodiscard]] uint64_t dropped_messages() const;

 private:
  struct Impl;
  std::shared_ptr<Impl> impl_;
};

}  // namespace rack::gui
