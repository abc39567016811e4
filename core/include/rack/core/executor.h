// The executor: runs the components of one host. rackd is a thin main around it;
// tests use it in-process.
//
// start(): attach every component to the router (mailboxes), init() each (non-RT;
// an init() that throws leaves that component in ERROR and nothing else), start the
// command and data tasks with the priority, CPU and stack from the host file, join
// the LCM network, then switch on the components marked autostart (dependencies
// first). stop(): OFF in reverse dependency order, stop and join every task,
// cleanup() each, leave the network.
//
// Real-time contract: not RT-safe; call from the main (non-RT) thread.
// Thread-safety: start/stop from one thread; status() from any non-RT thread.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "rack/core/data_component.h"
#include "rack/core/host_config.h"
#include "rack/rt/thread.h"
#include "rack/tims/lcm_transport.h"

namespace rack {

struct ExecutorOptions {
  bool allow_rt_fallback = true;   // run SCHED_OTHER when SCHED_FIFO is refused
  std::string lcm_url_override;    // replaces the host file's lcm_url when not empty
  std::function<void(const std::string&)> log;  // executor events; default stderr
};

struct ComponentView {
  Component* component = nullptr;
  bool realtime = false;           // tasks run SCHED_FIFO
  std::string init_error;
};

class Executor {
 public:
  Executor(std::unique_ptr<LoadedHost> host, ExecutorOptions options);
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  // Throws std::runtime_error when a task cannot start or the network cannot be
  // joined; what was started is stopped again.
  void start();
  void stop();  // idempotent

  [[nodiscard]] const HostSettings& settings() const noexcept { return host_->settings; }
  [[nodiscard]] tims::Router& router() noexcept { return router_; }
  [[nodiscard]] const std::vector<ComponentView>& components() const noexcept { return views_; }
  [[nodiscard]] Component* find(const std::string& name_or_address) noexcept;
  // The executor's own endpoint, Executor(sys/host_id)#1: commands from main().
  [[nodiscard]] tims::Endpoint& endpoint() noexcept { return *endpoint_; }
  [[nodiscard]] tims::LcmTransport* transport() noexcept { return transport_.get(); }
  [[nodiscard]] bool any_fallback() const noexcept { return fallback_; }

  // One line per component: state, data task cycles/overruns/latency (for rackd).
  [[nodiscard]] std::string status_report() const;

 private:
  void log(const std::string& line) const;
  bool send_command(Component& c, int8_t type, int64_t timeout_ns, std::string& why);

  std::unique_ptr<LoadedHost> host_;
  ExecutorOptions options_;
  tims::Router router_;
  std::unique_ptr<tims::Mailbox> mailbox_;
  std::unique_ptr<tims::Endpoint> endpoint_;
  std::unique_ptr<tims::LcmTransport> transport_;
  std::vector<ComponentView> views_;
  std::vector<std::unique_ptr<rt::Thread>> threads_;
  bool started_ = false;
  bool fallback_ = false;
};

}  // namespace rack
