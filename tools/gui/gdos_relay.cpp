#include "gdos_relay.h"

#include <cstdio>
#include <exception>
#include <memory>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "gdos_view.h"
#include "rack/tims/gdos_lcm.h"

namespace rack::gui {

namespace {

template <typename It>
std::string gdos_message(It first, It last) {
  std::string m = "{\"type\":\"gdos\",\"records\":[";
  for (It it = first; it != last; ++it) {
    if (it != first) m += ',';
    m += *it;
  }
  return m + "]}";
}

std::string notice(const char* level, const std::string& text) {
  return nlohmann::json{{"type", "notice"}, {"level", level}, {"text", text}}.dump(
      -1, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace

GdosRelay::GdosRelay(std::string url, std::string channel, std::string key_file, Publish publish)
    : url_(std::move(url)),
      channel_(std::move(channel)),
      key_file_(std::move(key_file)),
      publish_(std::move(publish)) {}

GdosRelay::~GdosRelay() { stop(); }

void GdosRelay::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { run(); });
}

void GdosRelay::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

std::string GdosRelay::snapshot() const {
  const std::lock_guard lock(mutex_);
  return recent_.empty() ? std::string() : gdos_message(recent_.begin(), recent_.end());
}

void GdosRelay::set_class_name(uint32_t key, std::string name) {
  const std::lock_guard lock(mutex_);
  class_names_[key] = std::move(name);
}

void GdosRelay::run() {
  std::unique_ptr<tims::GdosSubscriber> sub;
  try {
    // A keyed network's log is signed: the same key file verifies it (as `gdos --key-file`).
    sub = std::make_unique<tims::GdosSubscriber>(url_, channel_, true, "rack-gui", key_file_);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rack-gui: GDOS: %s\n", e.what());
    publish_(notice("error", std::string("GDOS: ") + e.what()));
    return;
  }
  while (running_.load()) {
    std::vector<std::string> lines;
    try {
      sub->poll(100, [&](const tims::GdosRecord& r) {
        std::string name = r.name;
        if (name.empty()) name = sub->announced_name(r.source);
        std::string cls;  // the source's class as it describes itself (set_class_name)
        {
          const std::lock_guard lock(mutex_);
          const auto it = class_names_.find(r.source & 0xFFFF0000u);
          if (it != class_names_.end()) cls = it->second;
        }
        lines.push_back(gdos_view::json_line(r, name, cls));
      });
    } catch (const std::exception& e) {
      std::fprintf(stderr, "rack-gui: GDOS: %s\n", e.what());
    }
    const std::string w = sub->take_warnings();
    if (!w.empty()) publish_(notice("warning", "GDOS: " + w));
    if (lines.empty()) continue;
    {
      const std::lock_guard lock(mutex_);
      for (const auto& l : lines) {
        recent_.push_back(l);
        if (recent_.size() > kRecentLog) recent_.pop_front();
      }
    }
    publish_(gdos_message(lines.begin(), lines.end()));
  }
}

}  // namespace rack::gui
