#include "rack/core/executor.h"

#include <unistd.h>

#include <cstdio>
#include <iostream>
#include <stdexcept>

namespace rack {

using tims::Address;
namespace msg = tims::msg;

Executor::Executor(std::unique_ptr<LoadedHost> host, ExecutorOptions options)
    : host_(std::move(host)), options_(std::move(options)), router_(host_->settings.system) {
  for (auto& c : host_->components) views_.push_back(ComponentView{c.get(), false, {}});
}

Executor::~Executor() { stop(); }

void Executor::log(const std::string& line) const {
  if (options_.log) options_.log(line);
  else std::cerr << "rackd: " << line << std::endl;
}

Component* Executor::find(const std::string& name_or_address) noexcept {
  const auto parsed = tims::parse_address(name_or_address);
  for (auto& v : views_) {
    if (v.component->name() == name_or_address) return v.component;
    if (parsed && v.component->address() == parsed->component()) return v.component;
  }
  return nullptr;
}

bool Executor::send_command(Component& c, int8_t type, int64_t timeout_ns, std::string& why) {
  alignas(8) std::byte buf[512];
  const auto r = endpoint_->call(c.address(), type, std::span<std::byte>(buf), timeout_ns);
  if (r.status != tims::CallStatus::kOk) {
    why = tims::describe(r.status);
    return false;
  }
  if (r.reply.type != msg::kOk) {
    why = msg::name(r.reply.type) != nullptr ? msg::name(r.reply.type) : "unexpected reply";
    if (r.reply.type == msg::kError && !r.body.empty()) {
      const auto* text = reinterpret_cast<const char*>(r.body.data());
      why += std::string(": ") + std::string(text, strnlen(text, r.body.size()));
    }
    return false;
  }
  return true;
}

void Executor::start() {
  if (started_) return;
  started_ = true;
  const HostSettings& hs = host_->settings;
  const Address self = Address::make(hs.system, tims::classes::kExecutor, hs.host_id, 1);
  mailbox_ = std::make_unique<tims::Mailbox>(self, 16, 64 * 1024);
  router_.add(*mailbox_);
  endpoint_ = std::make_unique<tims::Endpoint>(router_, *mailbox_, 1);

  for (auto& v : views_) v.component->attach(router_);
  for (auto& v : views_) {
    if (!v.component->run_init(v.init_error)) {
      log("component '" + v.component->name() + "' " + v.component->address().str() + " is in ERROR: init() failed: " + v.init_error);
    }
  }
  try {
    for (auto& v : views_) {
      Component& c = *v.component;
      const ComponentSettings& s = c.settings();
      auto cmd = std::make_unique<rt::Thread>();
      const auto how = cmd->start({c.name().substr(0, 11) + ":cmd", s.command_task.priority, s.command_task.cpu,
                                   s.command_task.stack_bytes},
                                  [&c] { c.run_command_task(); }, options_.allow_rt_fallback);
      v.realtime = how == rt::ThreadStart::kRealTime;
      fallback_ = fallback_ || how == rt::ThreadStart::kFallback;
      threads_.push_back(std::move(cmd));
      if (auto* dc = dynamic_cast<DataComponentBase*>(&c); dc != nullptr && c.data_task_mode() != DataTaskMode::kNone) {
        auto data = std::make_unique<rt::Thread>();
        const auto how2 = data->start({c.name().substr(0, 10) + ":data", s.data_task.priority, s.data_task.cpu,
                                       s.data_task.stack_bytes},
                                      [dc] { dc->run_data_task(); }, options_.allow_rt_fallback);
        fallback_ = fallback_ || how2 == rt::ThreadStart::kFallback;
        threads_.push_back(std::move(data));
      }
    }
    const std::string url = options_.lcm_url_override.empty() ? hs.lcm_url : options_.lcm_url_override;
    if (hs.lcm && (!url.empty() || !hs.networks.empty())) {
      tims::LcmTransportConfig tc;
      tc.url = url;
      tc.networks = hs.networks;
      // --lcm replaces the first network's URL (tests and one-off runs).
      if (!tc.networks.empty() && !options_.lcm_url_override.empty()) tc.networks.front().url = url;
      tc.role = hs.role;
      tc.announce_period_ns = hs.announce_period_ns;
      tc.expiry_ns = hs.expiry_ns;
      tc.max_message_bytes = hs.max_message_bytes;
      tc.large_slots = hs.large_slots;
      tc.warn = [this](const std::string& s) { log(s); };
      transport_ = std::make_unique<tims::LcmTransport>(router_, tc);
      // Other hosts of this robot own the rest of its addresses: let the transport
      // decide (discovery) instead of answering NOT_AVAILABLE here.
      router_.set_system_shared(true);
      tims::HostInfo info;
      info.host = hs.host;
      info.system = hs.system;
      info.host_id = hs.host_id;
      info.role = hs.role;
      info.pid = static_cast<int32_t>(getpid());
      info.executor = self.component();
      for (const auto& v : views_) {
        info.components.push_back({v.component->address(), v.component->name(), v.component->settings().impl});
      }
      transport_->set_announcement(std::move(info));
      transport_->start();
      // Autostarted components subscribe to other hosts: let discovery fill first.
      transport_->wait_until_warm();
    }
  } catch (...) {
    stop();
    throw;
  }
  for (auto& v : views_) {
    Component& c = *v.component;
    if (!c.settings().autostart) continue;
    std::string why;
    if (!send_command(c, msg::kOn, c.settings().rpc_timeout_ns * 4, why)) {
      log("autostart of '" + c.name() + "' " + c.address().str() + " failed: " + why +
          " (it retries every " + std::to_string(c.settings().retry_ns / rt::kNsPerMs) + " ms)");
    }
  }
}

void Executor::stop() {
  if (!started_) return;
  started_ = false;
  // OFF in reverse dependency order: consumers before their producers.
  if (endpoint_) {
    for (auto it = views_.rbegin(); it != views_.rend(); ++it) {
      Component& c = *it->component;
      if (c.state() == ComponentState::kDisabled) continue;
      std::string why;
      if (!send_command(c, msg::kOff, c.settings().rpc_timeout_ns, why)) {
        log("OFF of '" + c.name() + "' failed: " + why);
      }
    }
  }
  for (auto& v : views_) v.component->request_stop();
  for (auto& t : threads_) t->join();
  threads_.clear();
  if (transport_) transport_->stop();
  for (auto it = views_.rbegin(); it != views_.rend(); ++it) it->component->run_cleanup();
  for (auto& v : views_) v.component->detach();
  if (mailbox_) router_.remove(mailbox_->address());
}

std::string Executor::status_report() const {
  std::string out;
  for (const auto& v : views_) {
    const Component& c = *v.component;
    wire::StatsReply s;
    c.fill_stats(s);
    char line[512];
    if (c.data_task_mode() == DataTaskMode::kPeriodic) {
      std::snprintf(line, sizeof line,
                    "  %-14s %-15s %-8s cycles %-7llu overruns %-3llu wake-up p50 %lld us p99 %lld us max %lld us, "
                    "published %llu, listeners %llu\n",
                    c.name().c_str(), c.address().str().c_str(), describe(c.state()),
                    static_cast<unsigned long long>(s.data.cycles), static_cast<unsigned long long>(s.data.overruns),
                    static_cast<long long>(s.data.latency_p50_ns / 1000), static_cast<long long>(s.data.latency_p99_ns / 1000),
                    static_cast<long long>(s.data.latency_max_ns / 1000), static_cast<unsigned long long>(s.published),
                    static_cast<unsigned long long>(s.listeners));
    } else if (c.data_task_mode() == DataTaskMode::kTriggered) {
      std::snprintf(line, sizeof line, "  %-14s %-15s %-8s cycles %-7llu (triggered), published %llu, listeners %llu\n",
                    c.name().c_str(), c.address().str().c_str(), describe(c.state()),
                    static_cast<unsigned long long>(s.data.cycles), static_cast<unsigned long long>(s.published),
                    static_cast<unsigned long long>(s.listeners));
    } else {
      std::snprintf(line, sizeof line, "  %-14s %-15s %-8s commands %llu\n", c.name().c_str(),
                    c.address().str().c_str(), describe(c.state()), static_cast<unsigned long long>(s.commands));
    }
    out += line;
  }
  if (transport_) {
    const auto t = transport_->counters();
    char line[512];
    const auto u = [](uint64_t x) { return static_cast<unsigned long long>(x); };
    std::snprintf(line, sizeof line,
                  "  TiMS/LCM: packets in %llu out %llu, malformed %llu, forged %llu, undeliverable %llu, "
                  "sequence gaps %llu, lost %llu, forwarded %llu, not available %llu, hosts %zu, expired %llu, "
                  "subscriptions failed %llu\n",
                  u(t.packets_in), u(t.packets_out), u(t.malformed), u(t.forged), u(t.delivery_failed),
                  u(t.sequence_gaps), u(t.lost_messages), u(t.forwarded), u(t.not_available),
                  transport_->hosts().size(), u(t.hosts_expired), u(t.subscriptions_failed));
    out += line;
  }
  return out;
}

}  // namespace rack
