// Helpers shared by the unit tests: a watchdog for threaded tests, a small
// message body with an id, the generator-and-monitor host, a host-file loader with
// the built-in classes, and an in-process executor driven by messages.
//
// Nothing here is RT-safe; it is test code.
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "rack/components/builtin.h"
#include "rack/core/executor.h"
#include "rack/core/host_config.h"
#include "rack/core/registry.h"
#include "rack/core/stepper.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/clock.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/router.h"

namespace rack::test {

// Aborts the process when a threaded test hangs (a deadlock would otherwise only be
// caught by ctest's TIMEOUT, without saying which test). Generous by design: it is a
// watchdog, not a timing assertion.
class Watchdog {
 public:
  explicit Watchdog(std::chrono::seconds limit = std::chrono::seconds(30))
      : name_(current_test_name()), thread_([this, limit] { watch(limit); }) {}
  ~Watchdog() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  Watchdog(const Watchdog&) = delete;
  Watchdog& operator=(const Watchdog&) = delete;

 private:
  static std::string current_test_name() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    return info == nullptr ? "?" : std::string(info->test_suite_name()) + "." + info->name();
  }
  void watch(std::chrono::seconds limit) {
    std::unique_lock lock(mutex_);
    if (!cv_.wait_for(lock, limit, [this] { return done_; })) {
      std::fprintf(stderr, "WATCHDOG: test %s did not finish within %lld s; aborting\n", name_.c_str(),
                   static_cast<long long>(limit.count()));
      std::fflush(stderr);
      std::abort();
    }
  }

  std::string name_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;  // last: starts after the members above exist
};

// A body that identifies a message in ordering tests.
struct Tag {
  uint32_t id = 0;
  uint32_t pad = 0;
};

inline tims::MessageHeader tag_header(tims::Address dest, tims::Address src, uint8_t priority,
                                      int8_t type = tims::msg::kData) {
  return tims::make_header(dest, src, type, priority, 0, sizeof(Tag));
}

inline constexpr int64_t kCallTimeoutNs = 5 * rt::kNsPerSec;  // watchdog for RPCs

// Polls `pred` until it holds or `limit` passes. Returns the last result.
inline bool eventually(const std::function<bool()>& pred,
                       std::chrono::milliseconds limit = std::chrono::milliseconds(10000)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  for (;;) {
    if (pred()) return true;
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

// The host of the declared-input and stepper tests, without LCM: a generator `gen`
// (10 ms, ring 64) and a monitor `mon` of it (triggered: every sample), both instance
// 1 and retrying ON every 100 ms (the monitor every `retry_ms`). `monitor_params`
// follows `source: gen` in the monitor's params (", silence_ms: 200").
inline std::string generator_monitor_yaml(const std::string& monitor_params = "", int retry_ms = 100) {
  return R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    instance: 1
    retry_ms: 100
    data_task: {period_ms: 10, ring: 64}
  - name: mon
    class: Monitor
    instance: 1
    retry_ms: )" +
         std::to_string(retry_ms) + R"(
    params: {source: gen)" +
         monitor_params + R"(}
)";
}

// HostUnderTest's (or HostFileLoader's) `extra` for one test class: `T`, made by its
// default constructor, registered by `name` with class id kFirstUser.
template <class T>
std::function<void(ComponentRegistry&)> one_class(const char* name, const char* doc) {
  return [name, doc](ComponentRegistry& r) {
    r.add({name, tims::classes::kFirstUser, doc, [] { return std::make_unique<T>(); }});
  };
}

// A load's errors or warnings, one a line (file:line:col: message), for assertion
// messages and searches.
inline std::string text_of(const std::vector<ConfigError>& list) {
  std::string out;
  for (const auto& e : list) out += e.str() + "\n";
  return out;
}

// The component `name` of a loaded host, or nullptr.
inline const Component* component_named(const LoadResult& r, const std::string& name) {
  if (!r.host) return nullptr;
  for (const auto& c : r.host->components) {
    if (c->name() == name) return c.get();
  }
  return nullptr;
}

// Host-file text loaded as rackd loads it, with the built-in classes (and those
// `extra` registers) on a machine whose CPUs 0 and 1 are online, and nothing started:
// for tests of what the loader takes, warns about and refuses.
class HostFileLoader {
 public:
  explicit HostFileLoader(const std::function<void(ComponentRegistry&)>& extra = {}) {
    components::register_builtin(registry_);
    if (extra) extra(registry_);
    caps_.online_cpus = {0, 1};
  }
  // `file` is the name the errors and warnings give.
  LoadResult load(const std::string& text, const std::string& file) {
    return load_host_text(text, file, registry_, caps_);
  }

 private:
  ComponentRegistry registry_;
  rt::RtCapabilities caps_;
};

// How a HostUnderTest runs its components' tasks.
enum class Stepping : uint8_t {
  kThreads,  // as rackd does: a thread per task, real time
  kStepped,  // no task threads, a virtual clock (rack/core/stepper.h): requests are
             // answered when sent, data tasks run under stepper() (run_for, step)
};

// An executor built from host-file text, plus a tool mailbox in the same process
// (Tool(sys/1)#1 for replies, Tool(sys/1)#2 for streamed data) that the test drives
// the components from.
class HostUnderTest {
 public:
  static constexpr uint32_t kReplySlotSize = 64 * 1024;

  // `extra` registers test-only component classes beside the built-in ones.
  // `capture_gdos`: the components' GDOS lines go to gdos_log() as well (the sink
  // allocates in the GDOS thread: not for the no-allocation tests).
  // `stepping`: kStepped installs an rt::VirtualClock (at rt::VirtualClock's default
  // start) for the host's lifetime and makes the executor stepped (`lcm: false` hosts).
  explicit HostUnderTest(const std::string& yaml, const std::function<void(ComponentRegistry&)>& extra = {},
                         bool capture_gdos = false, Stepping stepping = Stepping::kThreads) {
    if (stepping == Stepping::kStepped) clock_ = std::make_unique<rt::VirtualClock>();
    components::register_builtin(registry_);
    if (extra) extra(registry_);
    auto loaded = load_host_text(yaml, "test.yaml", registry_, rt::probe_capabilities());
    if (!loaded.errors.empty()) throw std::runtime_error("host file rejected:\n" + text_of(loaded.errors));
    ExecutorOptions options;
    options.log = [this](const std::string& line) {
      std::lock_guard lock(log_mutex_);
      log_ += line + "\n";
    };
    if (capture_gdos) {
      options.gdos_sink = [this](const gdos::Record& r) {
        std::lock_guard lock(log_mutex_);
        gdos::append_line(r, gdos_log_);
      };
    }
    options.stepped = stepping == Stepping::kStepped;
    executor_ = std::make_unique<Executor>(std::move(loaded.host), std::move(options));
    const uint8_t sys = executor_->settings().system;
    reply_mailbox_ = std::make_unique<tims::Mailbox>(tims::Address::make(sys, tims::classes::kTool, 1, 1), 16,
                                                     kReplySlotSize);
    data_mailbox_ = std::make_unique<tims::Mailbox>(tims::Address::make(sys, tims::classes::kTool, 1, 2), 256, 1024);
    executor_->router().add(*reply_mailbox_);
    executor_->router().add(*data_mailbox_);
    endpoint_ = std::make_unique<tims::Endpoint>(executor_->router(), *reply_mailbox_, 10);
    executor_->start();
    if (clock_) stepper_ = std::make_unique<Stepper>(*executor_);
  }
  ~HostUnderTest() {
    // The executor's components may still send to the tool mailboxes until stopped.
    executor_->stop();
    executor_->router().remove(reply_mailbox_->address());
    executor_->router().remove(data_mailbox_->address());
  }
  HostUnderTest(const HostUnderTest&) = delete;
  HostUnderTest& operator=(const HostUnderTest&) = delete;

  Executor& executor() { return *executor_; }
  // Stepping::kStepped only: the stepper and its virtual clock.
  Stepper& stepper() {
    if (!stepper_) throw std::logic_error("HostUnderTest: not stepped (Stepping::kStepped)");
    return *stepper_;
  }
  rt::VirtualClock& clock() { return stepper().clock(); }
  tims::Endpoint& endpoint() { return *endpoint_; }
  tims::Mailbox& data_mailbox() { return *data_mailbox_; }
  std::string log() {
    std::lock_guard lock(log_mutex_);
    return log_;
  }
  // The components' GDOS lines (only with capture_gdos).
  std::string gdos_log() {
    std::lock_guard lock(log_mutex_);
    return gdos_log_;
  }

  tims::Address address_of(const std::string& name) {
    Component* c = executor_->find(name);
    if (c == nullptr) throw std::runtime_error("no component " + name);
    return c->address();
  }

  struct Reply {
    tims::CallStatus status = tims::CallStatus::kTimeout;
    int8_t type = 0;
    std::string body;  // bytes of the reply body
    [[nodiscard]] std::string error_text() const { return std::string(body.c_str()); }
  };

  Reply call(tims::Address dest, int8_t type, const void* body = nullptr, std::size_t size = 0,
             int64_t timeout_ns = kCallTimeoutNs) {
    const tims::ConstBuffer part{body, size};
    const std::span<const tims::ConstBuffer> parts(&part, size == 0 ? 0 : 1);
    const auto r = endpoint_->call(dest, type, parts, std::span<std::byte>(buffer_.get(), kReplySlotSize), timeout_ns);
    Reply out;
    out.status = r.status;
    if (r.status == tims::CallStatus::kOk) {
      out.type = r.reply.type;
      out.body.assign(reinterpret_cast<const char*>(r.body.data()), r.body.size());
    }
    return out;
  }
  template <typename T>
  Reply call_with(tims::Address dest, int8_t type, const T& body) {
    return call(dest, type, &body, sizeof body);
  }

  // GET_STATUS answer: msg::kEnabled, kDisabled or kError (0 when there was no answer).
  int8_t status(tims::Address dest) {
    const Reply r = call(dest, tims::msg::kGetStatus);
    return r.status == tims::CallStatus::kOk ? r.type : int8_t{0};
  }
  bool wait_status(tims::Address dest, int8_t expected,
                   std::chrono::milliseconds limit = std::chrono::milliseconds(10000)) {
    return eventually([&] { return status(dest) == expected; }, limit);
  }

  Reply set_param(tims::Address dest, const char* name, wire::ParamKind kind, int64_t int_value,
                  double float_value = 0.0, const char* text = nullptr) {
    wire::ParamRecord r;
    wire::copy_text(r.name, name);
    r.kind = static_cast<uint8_t>(kind);
    r.int_value = int_value;
    r.float_value = float_value;
    if (text != nullptr) wire::copy_text(r.string_value, text);
    return call_with(dest, tims::msg::kSetParam, r);
  }
  Reply set_bool(tims::Address dest, const char* name, bool value) {
    return set_param(dest, name, wire::ParamKind::kBool, value ? 1 : 0);
  }

  wire::StatsReply stats(tims::Address dest) {
    const Reply r = call(dest, tims::msg::kGetStats);
    wire::StatsReply s;
    if (r.status == tims::CallStatus::kOk && r.type == tims::msg::kStats && r.body.size() == sizeof s) {
      std::memcpy(&s, r.body.data(), sizeof s);
    } else {
      ADD_FAILURE() << "GET_STATS failed";
    }
    return s;
  }

  // GET_DATA (newest) decoded as SampleHeader + T. false when no DATA came back.
  template <typename T>
  bool get_data(tims::Address dest, wire::SampleHeader& header, T& sample, int64_t time_ns = 0) {
    wire::GetDataRequest req;
    req.time_ns = time_ns;
    const Reply r = time_ns == 0 ? call(dest, tims::msg::kGetData) : call_with(dest, tims::msg::kGetData, req);
    if (r.status != tims::CallStatus::kOk || r.type != tims::msg::kData ||
        r.body.size() != sizeof header + sizeof sample) {
      return false;
    }
    std::memcpy(&header, r.body.data(), sizeof header);
    std::memcpy(&sample, r.body.data() + sizeof header, sizeof sample);
    return true;
  }

 private:
  std::unique_ptr<rt::VirtualClock> clock_;  // first: it outlives the executor's stop()
  ComponentRegistry registry_;
  std::unique_ptr<Executor> executor_;
  std::unique_ptr<Stepper> stepper_;
  std::unique_ptr<tims::Mailbox> reply_mailbox_;
  std::unique_ptr<tims::Mailbox> data_mailbox_;
  std::unique_ptr<tims::Endpoint> endpoint_;
  std::unique_ptr<std::byte[]> buffer_{new std::byte[kReplySlotSize]};
  std::mutex log_mutex_;
  std::string log_, gdos_log_;
};

}  // namespace rack::test
