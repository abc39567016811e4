// Host file loading from text: every validation error names its line and key; a
// valid file yields components in dependency order.
#include "rack/components/class_ids.h"
#include "rack/core/host_config.h"

#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "rack/components/builtin.h"
#include "rack/rt/clock.h"
#include "rack/tims/lcm_url.h"

namespace rack {
namespace {

class HostConfigTest : public ::testing::Test {
 protected:
  HostConfigTest() {
    components::register_builtin(registry_);
    caps_.online_cpus = {0, 1};  // fixed, so "not online" does not depend on the machine
  }

  LoadResult load(const std::string& text) { return load_host_text(text, "host.yaml", registry_, caps_); }

  // Expects the text to be rejected with an error on `line` whose message contains
  // every one of `words`.
  void expect_error(const std::string& text, int line, std::initializer_list<const char*> words) {
    const LoadResult r = load(text);
    EXPECT_EQ(r.host, nullptr);
    ASSERT_FALSE(r.errors.empty()) << "accepted:\n" << text;
    std::string all;
    for (const auto& e : r.errors) all += "  " + e.str() + "\n";
    bool found = false;
    for (const auto& e : r.errors) {
      if (e.line != line) continue;
      bool has_all = true;
      for (const char* w : words) has_all = has_all && e.message.find(w) != std::string::npos;
      if (has_all) {
        found = true;
        EXPECT_EQ(e.file, "host.yaml");
        EXPECT_GT(e.column, 0);
        EXPECT_EQ(e.str().rfind("host.yaml:" + std::to_string(line) + ":", 0), 0u) << e.str();
      }
    }
    EXPECT_TRUE(found) << "no error on line " << line << " naming the key; got:\n" << all;
  }

  ComponentRegistry registry_;
  rt::RtCapabilities caps_;
};

// Line numbers in the texts below are written in the comments at the right.
TEST_F(HostConfigTest, UnknownTopLevelKey) {
  expect_error(R"(system: 0
lcm: false
colour: red
components: []
)",
               3, {"unknown key 'colour'"});
}

TEST_F(HostConfigTest, UnknownComponentAndTaskKeys) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    speed: 3
    data_task: {period_ms: 10}
)",
               5, {"unknown key 'speed'"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      period_ms: 10
      timeout_ms: 100
)",
               7, {"unknown key 'timeout_ms'"});  // triggered-only key on a periodic class
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    command_task:
      priority: 30
      period_ms: 10
    data_task: {period_ms: 10}
)",
               7, {"unknown key 'period_ms'"});
}

TEST_F(HostConfigTest, WrongTypes) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    instance: one
    data_task: {period_ms: 10}
)",
               5, {"'instance'"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    autostart: maybe
    data_task: {period_ms: 10}
)",
               5, {"'autostart'"});
  expect_error(R"(lcm: maybe
components: []
)",
               1, {"'lcm'"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: ten}
)",
               5, {"'period_ms'"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
    params: [1, 2]
)",
               6, {"'params'"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      period_ms: 10
      priority: [1]
)",
               7, {"'priority'"});
}

TEST_F(HostConfigTest, ParameterValueOfTheWrongType) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
    params:
      amplitude: loud
)",
               7, {"'amplitude'"});
}

TEST_F(HostConfigTest, MissingRequiredParameter) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
  - name: mon
    class: Monitor
    params:
      period_ms: 50
)",
               6, {"missing required parameter 'source'"});
}

TEST_F(HostConfigTest, UnknownParameter) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
    params:
      amplitude: 2
      bogus: 1
)",
               8, {"unknown parameter 'bogus'", "amplitude"});
}

TEST_F(HostConfigTest, UnknownClass) {
  expect_error(R"(lcm: false
components:
  - name: thing
    class: Nope
)",
               4, {"unknown component class 'Nope'", "Generator"});
}

TEST_F(HostConfigTest, DuplicateAddress) {
  expect_error(R"(lcm: false
components:
  - name: a
    class: Generator
    instance: 1
    data_task: {period_ms: 10}
  - name: b
    class: Generator
    instance: 1
    data_task: {period_ms: 10}
)",
               7, {"Generator(0/1)", "'instance'"});
}

TEST_F(HostConfigTest, DuplicateName) {
  expect_error(R"(lcm: false
components:
  - name: a
    class: Generator
    data_task: {period_ms: 10}
  - name: a
    class: Probe
    data_task: {period_ms: 10}
)",
               6, {"duplicate component name 'a'"});
}

TEST_F(HostConfigTest, PriorityOutsideOneToNinetyNine) {
  for (const char* prio : {"0", "100", "-5"}) {
    expect_error(std::string(R"(lcm: false
components:
  - name: gen
    class: Generator
    command_task:
      priority: )") + prio +
                     R"(
    data_task: {period_ms: 10}
)",
                 6, {"'priority'", "1..99"});
  }
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      period_ms: 10
      priority: 100
)",
               7, {"'priority'"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      period_ms: 10
      priority: -1
)",
               7, {"'priority'", "0..99"});
}

// Priority 0 on a data task means normal scheduling (heavy components such as MCL).
TEST_F(HostConfigTest, DataTaskPriorityZeroIsNormalScheduling) {
  const auto r = load(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10, priority: 0}
)");
  ASSERT_TRUE(r.errors.empty()) << r.errors.front().str();
  EXPECT_EQ(r.host->components.at(0)->settings().data_task.priority, 0);
}

// CPU partitioning (`cpus:`): forms, defaults (the other set's complement), refusals.
TEST_F(HostConfigTest, CpusPartitioning) {
  const std::string comps = "components:\n  - name: gen\n    class: Generator\n    data_task: {period_ms: 10}\n";
  {
    const LoadResult r = load("lcm: false\ncpus: {rt: 1}\n" + comps);
    ASSERT_NE(r.host, nullptr) << (r.errors.empty() ? "" : r.errors.front().str());
    EXPECT_EQ(r.host->settings.rt_cpus, std::vector<int>({1}));
    EXPECT_EQ(r.host->settings.housekeeping_cpus, std::vector<int>({0}));  // online less rt
  }
  {
    const LoadResult r = load("lcm: false\ncpus: {rt: \"0-1\", housekeeping: [1, 1]}\n" + comps);
    ASSERT_NE(r.host, nullptr) << (r.errors.empty() ? "" : r.errors.front().str());
    EXPECT_EQ(r.host->settings.rt_cpus, std::vector<int>({0, 1}));
    EXPECT_EQ(r.host->settings.housekeeping_cpus, std::vector<int>({1}));  // overlap: rackd warns
  }
  {
    const LoadResult r = load("lcm: false\n" + comps);
    ASSERT_NE(r.host, nullptr);
    EXPECT_TRUE(r.host->settings.rt_cpus.empty());  // no partitioning
    EXPECT_TRUE(r.host->settings.housekeeping_cpus.empty());
  }
  expect_error("lcm: false\ncpus: {rt: \"0-1\"}\n" + comps, 2, {"no CPU is left for housekeeping"});
  expect_error("lcm: false\ncpus: {rt: 2}\n" + comps, 2, {"'cpus: rt'", "CPU 2 is not online", "0,1"});
  expect_error("lcm: false\ncpus: {rt: \"1,\"}\n" + comps, 2, {"'cpus: rt' must be a CPU number"});
  expect_error("lcm: false\ncpus: {rt: \"1-0\"}\n" + comps, 2, {"'cpus: rt' must be a CPU number"});
  expect_error("lcm: false\ncpus: {housekeeping: {a: 1}}\n" + comps, 2, {"'cpus: housekeeping'"});
  expect_error("lcm: false\ncpus: [0]\n" + comps, 2, {"'cpus' must be a map"});
}

TEST_F(HostConfigTest, TraceRingEvents) {
  const std::string comps = "components:\n  - name: gen\n    class: Generator\n    data_task: {period_ms: 10}\n";
  {
    const LoadResult r = load("lcm: false\n" + comps);
    ASSERT_NE(r.host, nullptr);
    EXPECT_EQ(r.host->settings.trace_ring_events, 4096u);  // the default
  }
  {
    const LoadResult r = load("lcm: false\ntrace_ring_events: 16384\n" + comps);
    ASSERT_NE(r.host, nullptr) << (r.errors.empty() ? "" : r.errors.front().str());
    EXPECT_EQ(r.host->settings.trace_ring_events, 16384u);
  }
  expect_error("lcm: false\ntrace_ring_events: 3000\n" + comps, 2, {"'trace_ring_events' = 3000", "power of two"});
  expect_error("lcm: false\ntrace_ring_events: 8\n" + comps, 2, {"'trace_ring_events' = 8", "outside 16..1048576"});
  expect_error("lcm: false\ntrace_ring_events: 2097152\n" + comps, 2, {"outside 16..1048576"});
  expect_error("lcm: false\ntrace_ring_events: many\n" + comps, 2, {"'trace_ring_events'", "power of two"});
  // The error names the file, the line and the column of the value.
  const LoadResult r = load("lcm: false\ntrace_ring_events: 3000\n" + comps);
  ASSERT_FALSE(r.errors.empty());
  EXPECT_EQ(r.errors.front().str().rfind("host.yaml:2:20: ", 0), 0u) << r.errors.front().str();
}

TEST_F(HostConfigTest, PeriodicPhase) {
  const std::string head = "lcm: false\ncomponents:\n  - name: gen\n    class: Generator\n";
  {
    const LoadResult r = load(head + "    data_task: {period_ms: 10}\n");
    ASSERT_NE(r.host, nullptr);
    EXPECT_EQ(r.host->components.front()->settings().phase_ns, -1);  // default: from the start
  }
  {
    const LoadResult r = load(head + "    data_task: {period_ms: 10, phase_ms: 2.5}\n");
    ASSERT_NE(r.host, nullptr) << (r.errors.empty() ? "" : r.errors.front().str());
    EXPECT_EQ(r.host->components.front()->settings().phase_ns, 2'500'000);
  }
  expect_error(head + "    data_task: {period_ms: 10, phase_ms: 10}\n", 5, {"'phase_ms' = 10", "below period_ms"});
  expect_error(head + "    data_task: {period_ms: 10, phase_ms: -1}\n", 5, {"'phase_ms' = -1", "at least 0"});
  expect_error(head + "    data_task: {period_ms: 10, phase_ms: soon}\n", 5, {"'phase_ms'"});
}

TEST_F(HostConfigTest, CpuNotOnline) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      period_ms: 10
      cpu: 7
)",
               7, {"CPU 7", "not online", "0,1"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    command_task: {cpu: -1}
    data_task: {period_ms: 10}
)",
               5, {"not online"});
}

TEST_F(HostConfigTest, NonPositivePeriod) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      period_ms: 0
)",
               6, {"'period_ms'", "positive"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      period_ms: -10
)",
               6, {"'period_ms'"});
  expect_error(R"(lcm: false
components:
  - name: gen
    class: Generator
    data_task:
      priority: 40
)",
               6, {"'period_ms'"});  // periodic without a period: reported at the data_task map
}

TEST_F(HostConfigTest, DependencyCycleBetweenTwoMonitors) {
  expect_error(R"(lcm: false
components:
  - name: mon_a
    class: Monitor
    params: {source: mon_b}
  - name: mon_b
    class: Monitor
    instance: 1
    params: {source: mon_a}
)",
               3, {"cycle", "mon_a"});
}

TEST_F(HostConfigTest, SelfDependencyAndUnknownReference) {
  expect_error(R"(lcm: false
components:
  - name: mon
    class: Monitor
    params: {source: mon}
)",
               5, {"depends on itself"});
  expect_error(R"(lcm: false
components:
  - name: mon
    class: Monitor
    params:
      source: nobody
)",
               6, {"'source'", "nobody"});
}

TEST_F(HostConfigTest, YamlSyntaxErrorHasALine) {
  expect_error(R"(lcm: false
components:
  - name: gen
    class: [Generator
)",
               5, {"YAML"});
}

TEST_F(HostConfigTest, ValidFileGivesComponentsInDependencyOrder) {
  const LoadResult r = load(R"yaml(host: unit
system: 3
host_id: 2
lcm: false
components:
  - name: mon
    class: Monitor
    instance: 4
    autostart: true
    retry_ms: 250
    data_task: {priority: 45, timeout_ms: 400, input_slots: 8}
    params:
      source: gen
      period_ms: 50
  - name: probe
    class: Probe
    data_task: {period_ms: 20, ring: 10}
    params: {label: hello, on_delay_ms: 5}
  - name: gen
    class: Generator
    instance: 1
    command_task: {priority: 31, cpu: 1, slots: 4}
    data_task: {period_ms: 10, priority: 61}
    params: {amplitude: 2.5}
  - name: mon2
    class: Monitor
    instance: 5
    params: {source: "Generator(3/1)"}
)yaml");
  ASSERT_TRUE(r.errors.empty()) << r.errors.front().str();
  ASSERT_NE(r.host, nullptr);
  const LoadedHost& h = *r.host;
  EXPECT_EQ(h.settings.host, "unit");
  EXPECT_EQ(h.settings.system, 3);
  EXPECT_EQ(h.settings.host_id, 2);
  EXPECT_FALSE(h.settings.lcm);
  ASSERT_EQ(h.components.size(), 4u);
  ASSERT_EQ(h.dependencies.size(), 4u);

  std::map<std::string, std::size_t> pos;
  for (std::size_t i = 0; i < h.components.size(); ++i) pos[h.components[i]->name()] = i;
  ASSERT_EQ(pos.size(), 4u);
  EXPECT_LT(pos["gen"], pos["mon"]) << "a producer starts before its consumer";
  EXPECT_LT(pos["gen"], pos["mon2"]) << "a reference by address orders too";
  EXPECT_EQ(h.dependencies[pos["mon"]], std::vector<std::size_t>{pos["gen"]});
  EXPECT_EQ(h.dependencies[pos["mon2"]], std::vector<std::size_t>{pos["gen"]});
  EXPECT_TRUE(h.dependencies[pos["gen"]].empty());
  EXPECT_TRUE(h.dependencies[pos["probe"]].empty());

  const Component& gen = *h.components[pos["gen"]];
  EXPECT_EQ(gen.address(), tims::Address::make(3, class_ids::kGenerator, 1));
  EXPECT_EQ(gen.settings().impl, "Generator");
  EXPECT_EQ(gen.settings().period_ns, 10 * rt::kNsPerMs);
  EXPECT_EQ(gen.settings().command_task.priority, 31);
  EXPECT_EQ(gen.settings().command_task.cpu, 1);
  EXPECT_EQ(gen.settings().command_slots, 4u);
  EXPECT_EQ(gen.settings().data_task.priority, 61);
  EXPECT_DOUBLE_EQ(gen.parameters().find("amplitude")->get_float(), 2.5);

  const Component& mon = *h.components[pos["mon"]];
  EXPECT_EQ(mon.address(), tims::Address::make(3, class_ids::kMonitor, 4));
  EXPECT_TRUE(mon.settings().autostart);
  EXPECT_EQ(mon.settings().retry_ns, 250 * rt::kNsPerMs);
  EXPECT_EQ(mon.settings().data_timeout_ns, 400 * rt::kNsPerMs);
  EXPECT_EQ(mon.settings().input_slots, 8u);
  EXPECT_EQ(mon.parameters().find("source")->get_string(), "gen");

  const Component& probe = *h.components[pos["probe"]];
  EXPECT_EQ(probe.address(), tims::Address::make(3, class_ids::kProbe, 0));
  EXPECT_EQ(probe.settings().ring_size, 10u);
  EXPECT_EQ(probe.parameters().find("label")->get_string(), "hello");
  EXPECT_EQ(probe.parameters().find("on_delay_ms")->get_int(), 5);
}

TEST_F(HostConfigTest, MissingComponentsIsAWholeFileError) {
  const LoadResult r = load("lcm: false\n");
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0].line, 0);
  EXPECT_NE(r.errors[0].message.find("'components'"), std::string::npos);
  EXPECT_EQ(r.errors[0].str(), "host.yaml: " + r.errors[0].message);
}

// The network's receive threads may run SCHED_FIFO, but never at or above a
// component's real-time task: the file is refused with the task that would wait.
TEST_F(HostConfigTest, ReceivePriorityMustStayBelowEveryRealTimeTask) {
  const LoadResult r = load(R"(tims:
  receive_priority: 45
components:
  - name: gen
    class: Generator
    command_task: {priority: 60}
    data_task: {priority: 45, period_ms: 10}
)");
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0].line, 2);
  EXPECT_EQ(r.errors[0].message,
            "'receive_priority' = 45 must be below every real-time task's priority; gen's data_task runs at 45");
  const LoadResult range = load("tims:\n  receive_priority: 99\ncomponents: []\n");
  ASSERT_EQ(range.errors.size(), 1u);
  EXPECT_NE(range.errors[0].message.find("'receive_priority' = 99 is outside 0..98"), std::string::npos)
      << range.errors[0].message;
  // Priority-0 tasks (normal scheduling, as MCL's) do not count.
  const LoadResult ok = load(R"(tims:
  receive_priority: 20
components:
  - name: gen
    class: Generator
    command_task: {priority: 30}
    data_task: {priority: 0, period_ms: 10}
)");
  ASSERT_NE(ok.host, nullptr) << (ok.errors.empty() ? "" : ok.errors.front().str());
  EXPECT_EQ(ok.host->settings.receive_priority, 20);
}

TEST_F(HostConfigTest, TimsSectionIsReadWithEveryKey) {
  const LoadResult r = load(R"(system: 3
host_id: 2
tims:
  role: system_router
  announce_ms: 500
  expiry_ms: 2000
  max_message_kib: 1024
  large_slots: 2
  receive_priority: 5
  networks:
    - {name: robot3, url: "udpm://239.255.76.67:7713?ttl=1", scope: robot}
    - {name: fleet, url: "udpm://239.255.76.68:7700?ttl=1", scope: fleet, compress: zstd, compress_min_kib: 8}
components: []
)");
  ASSERT_NE(r.host, nullptr) << (r.errors.empty() ? "" : r.errors.front().str());
  const HostSettings& hs = r.host->settings;
  EXPECT_EQ(hs.role, tims::NodeRole::kSystemRouter);
  EXPECT_EQ(hs.announce_period_ns, 500 * rt::kNsPerMs);
  EXPECT_EQ(hs.expiry_ns, 2000 * rt::kNsPerMs);
  EXPECT_EQ(hs.max_message_bytes, 1024u * 1024u + 4096u);
  EXPECT_EQ(hs.large_slots, 2u);
  EXPECT_EQ(hs.receive_priority, 5);
  ASSERT_EQ(hs.networks.size(), 2u);
  EXPECT_EQ(hs.networks[0].name, "robot3");
  EXPECT_EQ(hs.networks[0].scope, tims::NetworkScope::kRobot);
  EXPECT_EQ(hs.networks[0].compression, tims::Compression::kNone);
  EXPECT_EQ(hs.networks[1].url, "udpm://239.255.76.68:7700?ttl=1");
  EXPECT_EQ(hs.networks[1].scope, tims::NetworkScope::kFleet);
  EXPECT_EQ(hs.networks[1].compression, tims::Compression::kZstd);
  EXPECT_EQ(hs.networks[1].compress_min_bytes, 8u * 1024u);
}

TEST_F(HostConfigTest, TimsSectionErrorsNameTheirLine) {
  expect_error(R"(system: 0
tims:
  role: king
components: []
)",
               3, {"'role'", "king"});
  expect_error(R"(system: 0
tims:
  announce_ms: 1000
  expiry_ms: 500
components: []
)",
               4, {"'expiry_ms'", "longer than 'announce_ms'"});
  expect_error(R"(system: 0
tims:
  networks:
    - {name: a, url: "udpm://239.255.76.67:7711?ttl=1", scope: sideways}
components: []
)",
               4, {"'scope'", "sideways"});
  expect_error(R"(system: 0
tims:
  networks:
    - {name: a, url: "udpm://239.255.76.67:7711?ttl=1", compress: lzma}
components: []
)",
               4, {"'compress'", "lzma"});
  expect_error(R"(system: 0
lcm_url: "udpm://239.255.76.67:7667?ttl=0"
tims:
  networks:
    - {name: a, url: "udpm://239.255.76.67:7711?ttl=1"}
components: []
)",
               5, {"either 'lcm_url' or"});
  expect_error(R"(system: 0
tims:
  role: system_router
  networks:
    - {name: a, url: "udpm://239.255.76.67:7711?ttl=1", scope: robot}
components: []
)",
               5, {"system_router", "scope: fleet"});
  expect_error(R"(system: 0
tims:
  colour: blue
components: []
)",
               3, {"unknown key 'colour'"});
}

TEST_F(HostConfigTest, ReportsEveryProblemNotJustTheFirst) {
  const LoadResult r = load(R"(lcm: false
components:
  - name: a
    class: Generator
    data_task: {period_ms: 0}
  - name: b
    class: Nope
)");
  EXPECT_EQ(r.host, nullptr);
  EXPECT_GE(r.errors.size(), 2u);
}

// ---- mode-switch detection keys (configs/modeswitch_demo.yaml documents them)

TEST_F(HostConfigTest, ModeSwitchBlockAndTaskModes) {
  const LoadResult r = load(R"(system: 0
lcm: false
modeswitch:
  mode: abort
  abort: process
  crash_dir: /tmp/crashes
  rusage: true
  lock_wait_us: 50
  watchdog_periods: 3
  rttime_ms: 250
  allow_syscalls: [sched_yield, ioctl]
components:
  - name: generator
    class: Generator
    command_task: {priority: 30, modeswitch: off}
    data_task: {priority: 60, period_ms: 10, modeswitch: warn}
  - name: probe
    class: Probe
    data_task: {period_ms: 10}
)");
  ASSERT_NE(r.host, nullptr) << (r.errors.empty() ? "" : r.errors[0].str());
  const auto& ms = r.host->settings.modeswitch;
  EXPECT_EQ(ms.default_mode, rt::modeswitch::Mode::kAbort);
  EXPECT_EQ(ms.abort_action, rt::modeswitch::AbortAction::kProcess);
  EXPECT_EQ(ms.crash_dir, "/tmp/crashes");
  EXPECT_TRUE(ms.rusage);
  EXPECT_EQ(ms.lock_wait_ns, 50'000);
  EXPECT_EQ(ms.watchdog_periods, 3u);
  EXPECT_EQ(ms.rttime_us, 250'000);
  EXPECT_EQ(ms.allow_syscalls, (std::vector<std::string>{"sched_yield", "ioctl"}));
  const Component* gen = nullptr;
  const Component* probe = nullptr;
  for (const auto& c : r.host->components) (c->name() == "generator" ? gen : probe) = c.get();
  ASSERT_TRUE(gen != nullptr && probe != nullptr);
  EXPECT_EQ(gen->settings().command_task.modeswitch, rt::modeswitch::Mode::kOff);
  EXPECT_EQ(gen->settings().data_task.modeswitch, rt::modeswitch::Mode::kWarn);
  EXPECT_FALSE(probe->settings().data_task.modeswitch.has_value()) << "unset: the host default applies";
}

TEST_F(HostConfigTest, ModeSwitchErrorsNameTheirLine) {
  expect_error(R"(system: 0
lcm: false
modeswitch:
  mode: loud
components: []
)",
               4, {"'mode' must be off, warn or abort", "loud"});
  expect_error(R"(system: 0
lcm: false
modeswitch:
  allow_syscalls: [futex, fly]
components: []
)",
               4, {"'fly' is not a system call"});
  expect_error(R"(system: 0
lcm: false
modeswitch:
  abort: everything
  colour: red
components: []
)",
               4, {"'abort' must be component"});
  expect_error(R"(system: 0
lcm: false
components:
  - name: generator
    class: Generator
    data_task: {period_ms: 10, modeswitch: sometimes}
)",
               6, {"'modeswitch' must be off, warn or abort"});
}

}  // namespace
}  // namespace rack

namespace rack {
namespace {

TEST_F(HostConfigTest, CpuDmaLatencyIsReadAndRangeChecked) {
  LoadResult r = load("lcm: false\ncpu_dma_latency_us: 20\ncomponents: []\n");
  ASSERT_NE(r.host, nullptr);
  EXPECT_EQ(r.host->settings.cpu_dma_latency_us, 20);
  r = load("lcm: false\ncomponents: []\n");
  ASSERT_NE(r.host, nullptr);
  EXPECT_EQ(r.host->settings.cpu_dma_latency_us, 0) << "the default holds the shallowest idle state";
  expect_error("lcm: false\ncpu_dma_latency_us: -2\ncomponents: []\n", 2, {"'cpu_dma_latency_us'", "-1..100000"});
  expect_error("lcm: false\ncpu_dma_latency_us: low\ncomponents: []\n", 2, {"cpu_dma_latency_us"});
}

// ---- strict reading (issue 17): each rule, with file:line:col ----

const char* const kOneComponent = R"(components:
  - name: g
    class: Generator
    data_task: {period_ms: 10}
)";

TEST_F(HostConfigTest, DuplicateKeysAreRefusedAtEveryLevel) {
  expect_error(std::string("system: 0\nlcm: false\nsystem: 1\n") + kOneComponent, 3,
               {"duplicate key 'system'", "first at line 1"});
  expect_error(R"(lcm: false
components:
  - name: g
    class: Generator
    data_task: {period_ms: 10, period_ms: 20}
)",
               5, {"duplicate key 'period_ms'"});
  expect_error(R"(lcm: false
components:
  - name: g
    class: Generator
    data_task: {period_ms: 10}
    params:
      amplitude: 1
      amplitude: 2
)",
               8, {"duplicate key 'amplitude'", "first at line 7"});
  expect_error(R"(lcm: false
tims:
  announce_ms: 500
  announce_ms: 600
components: []
)",
               4, {"duplicate key 'announce_ms'"});
}

TEST_F(HostConfigTest, IntegersOutOfRangeNeverWrapAround) {
  expect_error(R"(lcm: false
components:
  - name: g
    class: Generator
    data_task: {period_ms: 10, cpu: 4294967297}
)",
               5, {"CPU 4294967297 is not online"});
  expect_error(R"(lcm: false
components:
  - name: g
    class: Generator
    data_task: {period_ms: 10, priority: 18446744073709551617}
)",
               5, {"'priority' must be"});
  expect_error(std::string("lcm: false\nsystem: 256\n") + kOneComponent, 2, {"'system' = 256 is outside 0..254"});
  expect_error(R"(lcm: false
components:
  - name: g
    class: Generator
    instance: -1
    data_task: {period_ms: 10}
)",
               5, {"'instance' = -1 is outside 0..255"});
  expect_error(R"(lcm: false
components:
  - name: g
    class: Generator
    data_task: {period_ms: 1e300}
)",
               5, {"'period_ms'", "above 86400000"});
}

TEST_F(HostConfigTest, MalformedUrlsAreRefusedWithTheTransportsParser) {
  expect_error(std::string("lcm_url: garbage\n") + kOneComponent, 1, {"'lcm_url'", "not an LCM URL"});
  expect_error(std::string("lcm_url: \"udpm://239.255.76.67:99999\"\n") + kOneComponent, 1, {"not a number 1..65535"});
  expect_error(std::string("lcm_url: \"udpm://10.0.0.1:7667\"\n") + kOneComponent, 1, {"not a multicast address"});
  expect_error(std::string("lcm_url: \"udpm://239.255.76.67:7667?tll=1\"\n") + kOneComponent, 1,
               {"unknown option 'tll'"});
  expect_error(std::string("gdos: {lcm_url: \"udpm://239.255.76.67:7667?ttl=300\"}\n") + kOneComponent, 1,
               {"'lcm_url'", "ttl '300'"});
  expect_error(std::string("tims:\n  networks:\n    - {name: robot, url: \"bogus://x\"}\n") + kOneComponent, 3,
               {"'url'", "unknown LCM provider 'bogus'"});
}

TEST_F(HostConfigTest, ASecondDocumentIsRefusedEvenWhenItIsBroken) {
  expect_error(std::string("lcm: false\n") + kOneComponent + "---\nlcm: true\n", 6, {"a second YAML document"});
  expect_error(std::string("lcm: false\n") + kOneComponent + "---\n{[ broken\n", 8,
               {"after the host file's document", "YAML syntax"});
  expect_error(std::string("lcm: false\n") + kOneComponent + "...\n---\nx: 1\n", 7, {"a second YAML document"});
  // One document with a leading '---' is fine.
  EXPECT_NE(load(std::string("---\nlcm: false\n") + kOneComponent).host, nullptr);
}

TEST_F(HostConfigTest, ExpiryMustBeAtLeastTwiceTheAnnouncePeriod) {
  expect_error(std::string("tims:\n  announce_ms: 5000\n") + kOneComponent, 2,
               {"at least twice 'announce_ms'", "5000 ms"});
  expect_error(std::string("tims:\n  announce_ms: 1000\n  expiry_ms: 1500\n") + kOneComponent, 3,
               {"'expiry_ms' (1500 ms)", "at least twice"});
  EXPECT_NE(load(std::string("lcm: false\ntims:\n  announce_ms: 1000\n  expiry_ms: 2000\n") + kOneComponent).host,
            nullptr);
}

TEST_F(HostConfigTest, NamesAreCheckedForLengthAndCharacters) {
  expect_error(std::string("host: ") + std::string(100000, 'a') + "\n" + kOneComponent, 1,
               {"a value of 100000 bytes", "at most 4096"});
  expect_error(std::string("host: ") + std::string(64, 'a') + "\n" + kOneComponent, 1, {"host name", "1..63"});
  expect_error(std::string("host: \"robot\\x1b[2J\"\n") + kOneComponent, 1, {"control character (U+001B)"});
  expect_error(std::string("host: \"a\\0b\"\n") + kOneComponent, 1, {"a NUL byte"});
  expect_error(std::string("host: \"a\\u2028b\"\n") + kOneComponent, 1, {"control character (U+2028)"});
  expect_error(R"(lcm: false
components:
  - name: "g\tx"
    class: Generator
    data_task: {period_ms: 10}
)",
               3, {"component name"});
  expect_error(std::string("gdos: {channel: \"RACK GDOS\"}\n") + kOneComponent, 1, {"'channel'"});
  expect_error(std::string("tims:\n  networks:\n    - {name: \"robot net\", url: \"udpm://239.255.76.67:7667\"}\n") +
                   kOneComponent,
               3, {"network name"});
}

TEST_F(HostConfigTest, RawBytesMustBeUtf8TextWithoutNulOrControlCharacters) {
  expect_error(std::string("lcm: false\nhost: a") + std::string(1, '\0') + "b\n" + kOneComponent, 2, {"a NUL byte"});
  expect_error(std::string("lcm: false\nhost: a\xff\n") + kOneComponent, 2, {"invalid UTF-8 (byte 0xff)"});
  expect_error(std::string("lcm: false\nhost: a\xc0\xaf"
                           "b\n") +
                   kOneComponent,
               2, {"invalid UTF-8"});  // overlong
  expect_error(std::string("lcm: false\nhost: a\x07\n") + kOneComponent, 2, {"control character (U+0007)"});
  // UTF-8 in a comment or a free-text value is fine.
  EXPECT_NE(load(std::string("lcm: false  # Büro, 東京\n") + kOneComponent).host, nullptr);
}

TEST_F(HostConfigTest, MessagesQuotingTheFileAreCleanTextOfBoundedLength) {
  // A key with an escape and a newline, given twice: the duplicate's message quotes it.
  const LoadResult r = load(std::string("lcm: false\n\"k\\e[2J\\nhost.yaml:1:1: fake\": 1\n") +
                            "\"k\\e[2J\\nhost.yaml:1:1: fake\": 2\n" + kOneComponent);
  ASSERT_FALSE(r.errors.empty());
  for (const auto& e : r.errors) {
    for (const char c : e.message) EXPECT_GE(static_cast<unsigned char>(c), 0x20u) << e.message;
    EXPECT_LE(e.message.size(), 1024u + 6u);
  }
}

TEST_F(HostConfigTest, SizeAndNestingAreBounded) {
  const LoadResult big = load(std::string(kMaxHostFileBytes + 1, '#'));
  ASSERT_EQ(big.errors.size(), 1u);
  EXPECT_NE(big.errors[0].message.find("at most 1048576"), std::string::npos) << big.errors[0].str();
  std::string deep = "lcm: false\nx: ";
  for (int i = 0; i < 40; ++i) deep += "[";
  for (int i = 0; i < 40; ++i) deep += "]";
  expect_error(deep + "\n" + kOneComponent, 2, {"nested deeper than 32"});
  // yaml-cpp's own recursion guard, far deeper: an error, not a stack overflow.
  const LoadResult deeper = load("x: " + std::string(100000, '['));
  EXPECT_EQ(deeper.host, nullptr);
  EXPECT_FALSE(deeper.errors.empty());
}

class HostFileReadTest : public HostConfigTest {
 protected:
  std::string path(const char* name) { return std::string(dir_) + "/" + name; }
  HostFileReadTest() {
    char tmpl[] = "/tmp/rack_host_read_XXXXXX";
    dir_ = mkdtemp(tmpl);
  }
  ~HostFileReadTest() override { std::filesystem::remove_all(dir_); }
  std::string dir_;
};

TEST_F(HostFileReadTest, OnlyRegularFilesWithinTheSizeLimitAreRead) {
  const std::string fifo = path("fifo.yaml");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  auto r = load_host_file(fifo, registry_, caps_);  // must not block (opened non-blocking)
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("is a FIFO"), std::string::npos) << r.errors[0].str();
  r = load_host_file("/dev/zero", registry_, caps_);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("is a device"), std::string::npos) << r.errors[0].str();
  r = load_host_file(dir_, registry_, caps_);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("is a directory"), std::string::npos) << r.errors[0].str();
  const std::string big = path("big.yaml");
  {
    std::FILE* f = std::fopen(big.c_str(), "w");
    ASSERT_NE(f, nullptr);
    ASSERT_EQ(ftruncate(fileno(f), 50 << 20), 0);  // 50 MiB, sparse: refused by fstat, never read
    std::fclose(f);
  }
  r = load_host_file(big, registry_, caps_);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("52428800 bytes: at most 1048576"), std::string::npos) << r.errors[0].str();
  const std::string ok = path("ok.yaml");
  {
    std::FILE* f = std::fopen(ok.c_str(), "w");
    std::fputs((std::string("lcm: false\n") + kOneComponent).c_str(), f);
    std::fclose(f);
  }
  r = load_host_file(ok, registry_, caps_);
  EXPECT_TRUE(r.errors.empty());
  EXPECT_NE(r.host, nullptr);
}

TEST(LcmUrlTest, ParsesWhatLcmTakesAndRefusesTheRest) {
  auto u = tims::parse_lcm_url("udpm://239.255.76.67:7667?ttl=1&recv_buf_size=4194304");
  ASSERT_TRUE(u.ok()) << u.error;
  EXPECT_EQ(u.url.provider, "udpm");
  EXPECT_EQ(u.url.port, 7667);
  EXPECT_EQ(u.url.ttl, 1);
  EXPECT_EQ(u.url.recv_buf_size, 4194304);
  EXPECT_EQ(u.url.group, 0xEFFF4C43u);
  EXPECT_TRUE(tims::parse_lcm_url("udpm://").ok());
  EXPECT_TRUE(tims::parse_lcm_url("memq://").ok());
  EXPECT_TRUE(tims::parse_lcm_url("file:///tmp/x.lcm?mode=w").ok());
  for (const char* bad : {"",
                          "garbage",
                          "udpm:/239.255.76.67",
                          "udpm://239.255.76.67:0",
                          "udpm://239.255.76.67:65536",
                          "udpm://239.255.76.67:-1",
                          "udpm://239.255.76.67:76a",
                          "udpm://1.2.3.4:7667",
                          "udpm://239.255.76.67:7667?ttl=256",
                          "udpm://239.255.76.67:7667?ttl=-1",
                          "udpm://239.255.76.67:7667?ttl=1&ttl=2",
                          "udpm://239.255.76.67:7667?",
                          "udpm://239.255.76.67:7667?ttl=1&",
                          "udpm://239.255.76.67:7667?recv_buf_size=0",
                          "udpm://239.255.76.67:7667?recv_buf_size=99999999999999999999",
                          "udpm://239.255.76.67 :7667",
                          "memq://x",
                          "tcpq://",
                          "file://",
                          "file:///x?mode=q",
                          "bogus://x"}) {
    EXPECT_FALSE(tims::parse_lcm_url(bad).ok()) << "accepted '" << bad << "'";
  }
  EXPECT_FALSE(tims::parse_lcm_url(std::string(300, 'u')).ok());
}

}  // namespace
}  // namespace rack
