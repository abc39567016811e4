// rack-gui's log view: a thread of its own receives the GDOS log of every host
// (tims::GdosSubscriber, signed logs verified with the network's key file) and passes
// it on to the browsers in batches, as {"type":"gdos","records":[..]} (each record as
// gdos_view::json_line gives it); the last kRecentLog records are kept for browsers
// that connect later. A subscriber that cannot be opened, or warns (malformed or
// forged records), is reported as a "notice".
//
// Not RT code (a tool). Thread-safety: start() and stop() from one thread; snapshot()
// from any thread; `publish` is called from the relay's thread.
#pragma once

#include <atomic>
#include <cstddef>
#include <deque>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

namespace rack::gui {

class GdosRelay {
 public:
  using Publish = std::function<void(std::string message)>;  // for every browser
  static constexpr std::size_t kRecentLog = 500;             // records kept for new browsers

  // `url`, `channel`: the GDOS network and channel; `key_file`: "" when it is not signed.
  GdosRelay(std::string url, std::string channel, std::string key_file, Publish publish);
  ~GdosRelay();
  GdosRelay(const GdosRelay&) = delete;
  GdosRelay& operator=(const GdosRelay&) = delete;

  void start();
  void stop();
  // The recent records as one "gdos" message ("" when there are none).
  [[nodiscard]] std::string snapshot() const;
  // The class name that sources of `key` (system << 24 | class id << 16) describe
  // (rack-gui links no class: its backend learns them by GET_CLASS). Any thread.
  void set_class_name(uint32_t key, std::string name);

 private:
  void run();

  const std::string url_;
  const std::string channel_;
  const std::string key_file_;
  const Publish publish_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  mutable std::mutex mutex_;                     // recent_: the relay's thread -> snapshot()
  std::deque<std::string> recent_;               // JSON records, oldest first
  std::map<uint32_t, std::string> class_names_;  // under mutex_ (set_class_name)
};

}  // namespace rack::gui
