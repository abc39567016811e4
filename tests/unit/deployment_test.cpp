// rack/client/deployment.h: host files read without the executor, the flows between
// their components, the networks they cross and the allocation per CPU (rackctl graph,
// rackctl alloc).
#include <gtest/gtest.h>

#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "rack/client/deployment.h"
#include "rack/components/class_ids.h"
#include "rack/core/wire.h"
#include "rack/core/wire_tasks.h"
#include "rack/tims/address.h"

namespace rack::deploy {
namespace {

std::string errors_of(const Host& h) {
  std::string out;
  for (const auto& e : h.errors) out += e.str() + "\n";
  return out;
}

// Robot 1: a producer on its sensor computer, a consumer on its main computer (system
// router); robot 2: a consumer across the fleet link.
constexpr const char* kAux = R"Y(host: r1-aux
system: 1
host_id: 1
tims:
  networks:
    - {name: robot1, url: "udpm://239.255.76.67:7711?ttl=1", scope: robot}
components:
  - name: scanner
    class: Generator
    instance: 0
    data_task: {priority: 60, period_ms: 10}
)Y";
constexpr const char* kMain = R"Y(host: r1-main
system: 1
tims:
  role: system_router
  networks:
    - {name: robot1, url: "udpm://239.255.76.67:7711?ttl=1", scope: robot}
    - {name: fleet, url: "udpm://239.255.76.68:7700?ttl=1", scope: fleet}
components:
  - name: monitor
    class: Monitor
    instance: 1
    data_task: {priority: 50}
    params:
      source: "Generator(1/0)"
)Y";
constexpr const char* kRobot2 = R"Y(host: r2-main
system: 2
tims:
  role: system_router
  networks:
    - {name: robot2, url: "udpm://239.255.76.69:7712?ttl=1", scope: robot}
    - {name: fleet, url: "udpm://239.255.76.68:7700?ttl=1", scope: fleet}
components:
  - name: far
    class: Monitor
    data_task: {priority: 50}
    params: {source: "Generator(1/0)"}
  - name: ghost
    class: Monitor
    instance: 1
    params: {source: "Generator(7/3)"}
)Y";

Deployment fleet() {
  return build(
      {read_host_text(kAux, "aux.yaml"), read_host_text(kMain, "main.yaml"), read_host_text(kRobot2, "r2.yaml")});
}

const Flow* flow_to(const Deployment& d, const std::string& consumer) {
  for (const auto& f : d.flows) {
    if (d.hosts[f.consumer_host].components[f.consumer].name == consumer) return &f;
  }
  return nullptr;
}

TEST(DeploymentTest, ReadsHostsComponentsAndTasks) {
  const Host h = read_host_text(kAux, "aux.yaml");
  ASSERT_TRUE(h.errors.empty()) << errors_of(h);
  EXPECT_EQ(h.host, "r1-aux");
  EXPECT_EQ(h.system, 1);
  EXPECT_EQ(h.host_id, 1);
  ASSERT_EQ(h.networks.size(), 1u);
  EXPECT_EQ(h.networks[0].scope, "robot");
  ASSERT_EQ(h.components.size(), 1u);
  const Component& c = h.components[0];
  EXPECT_EQ(c.impl, "Generator");
  // "Generator(1/0)" when TiMS knows the class, else
  // marked as a guess.
  EXPECT_EQ(c.address_text.rfind("Generator(1/0)", 0), 0u) << c.address_text;
  EXPECT_EQ(c.command_task.priority, 30);  // rackd's default when the file gives none
  EXPECT_EQ(c.data_task.priority, 60);
  EXPECT_EQ(c.period_ns, 10'000'000);
}

TEST(DeploymentTest, FlowsAcrossHostsAndNetworks) {
  const Deployment d = fleet();
  const Flow* local = flow_to(d, "monitor");
  ASSERT_NE(local, nullptr);
  ASSERT_NE(local->producer, kNone);
  EXPECT_EQ(d.hosts[local->producer_host].components[local->producer].name, "scanner");
  EXPECT_EQ(local->param, "source");
  EXPECT_EQ(local->period_ns, 10'000'000);
  EXPECT_EQ(local->networks, std::vector<std::string>{"robot1"});
  const Flow* far = flow_to(d, "far");
  ASSERT_NE(far, nullptr);
  EXPECT_EQ(far->networks, (std::vector<std::string>{"robot1", "fleet", "robot2"}));
  const Flow* ghost = flow_to(d, "ghost");
  ASSERT_NE(ghost, nullptr);
  EXPECT_EQ(ghost->producer, kNone);  // no given host file places Generator(7/3)
  const std::string dot = to_dot(d);
  EXPECT_NE(dot.find("not in these host files"), std::string::npos) << dot;
  EXPECT_NE(dot.find("via robot1 > fleet > robot2"), std::string::npos) << dot;
}

TEST(DeploymentTest, EachUnplacedProducerIsOneNode) {
  const Deployment d = build({read_host_text(R"Y(host: a
components:
  - {name: m1, class: Monitor, instance: 1, params: {source: "Generator(5/5)"}}
  - {name: m2, class: Monitor, instance: 2, params: {source: "Generator(4/4)"}}
  - {name: m3, class: Monitor, instance: 3, params: {source: "Generator(5/5)"}}
)Y",
                                             "a.yaml")});
  const std::string dot = to_dot(d);
  EXPECT_NE(dot.find("u_0 [label=\"Generator(5/5)\\nnot in these host files\""), std::string::npos) << dot;
  EXPECT_NE(dot.find("u_1 [label=\"Generator(4/4)\\nnot in these host files\""), std::string::npos) << dot;
  EXPECT_NE(dot.find("u_0 -> c0_0"), std::string::npos) << dot;
  EXPECT_NE(dot.find("u_1 -> c0_1"), std::string::npos) << dot;
  EXPECT_NE(dot.find("u_0 -> c0_2"), std::string::npos) << dot;
  EXPECT_EQ(dot.find("u_2"), std::string::npos) << dot;
}

TEST(DeploymentTest, FlowByNameInOneFileAndNotForPlainValues) {
  const Deployment d = build({read_host_text(R"Y(host: a
components:
  - {name: gen, class: Generator, data_task: {priority: 40, period_ms: 5}}
  - {name: cam, class: Camera, params: {source: /dev/video0}}
  - {name: mon, class: Monitor, instance: 2, data_task: {priority: 45}, params: {source: gen, source_period_ms: 0}}
)Y",
                                             "a.yaml")});
  ASSERT_EQ(d.flows.size(), 1u);
  EXPECT_EQ(d.flows[0].target, "gen");
  EXPECT_TRUE(d.flows[0].networks.empty());  // inside one host
  EXPECT_EQ(d.flows[0].line, 5);
}

TEST(DeploymentTest, ClassDescriptionsDecideWhichParametersAreFlows) {
  // Pilot's `mode` is a choice that happens to be the name of the Path component.
  const Host h = read_host_text(R"Y(host: a
components:
  - {name: path, class: PathPlanner, data_task: {priority: 20, period_ms: 200}}
  - {name: chassis, class: ChassisSim, data_task: {priority: 80, period_ms: 10}}
  - {name: pilot, class: Pilot, data_task: {priority: 66, period_ms: 50}, params: {path: path, mode: path, chassis: "Chassis(0/0)"}}
)Y",
                                "a.yaml");
  const Deployment guessed = build({h});
  EXPECT_EQ(guessed.flows.size(), 3u);  // path, mode (wrongly) and chassis
  const std::vector<ClassInfo> classes{{"PathPlanner", "Path", true, {}},
                                       {"ChassisSim", "Chassis", true, {}},
                                       {"Pilot", "Pilot", true, {"path", "chassis"}}};
  const Deployment d = build({h}, &classes);
  ASSERT_EQ(d.flows.size(), 2u);
  EXPECT_EQ(d.flows[0].param, "path");
  EXPECT_EQ(d.flows[1].param, "chassis");
  // Chassis(0/0) is the ChassisSim: the class's own name for its addresses.
  ASSERT_NE(d.flows[1].producer, kNone);
  EXPECT_EQ(d.hosts[0].components[d.flows[1].producer].name, "chassis");
  EXPECT_EQ(d.hosts[0].components[1].address_text.rfind("Chassis(0/0)", 0), 0u)
      << d.hosts[0].components[1].address_text;
}

TEST(DeploymentTest, FlagsConsumerAboveProducerAndSamePriorityOnOneCpu) {
  const Deployment d = build({read_host_text(R"Y(host: a
components:
  - {name: gen, class: Generator, data_task: {priority: 40, period_ms: 5, cpu: 1}}
  - {name: mon, class: Monitor, instance: 2, data_task: {priority: 45, cpu: 1}, params: {source: gen}}
  - {name: twin, class: Generator, instance: 3, data_task: {priority: 40, period_ms: 5, cpu: 1}}
  - {name: other, class: Generator, instance: 4, data_task: {priority: 40, period_ms: 5, cpu: 2}}
)Y",
                                             "a.yaml")});
  const CpuGroup* cpu1 = nullptr;
  const CpuGroup* cpu2 = nullptr;
  for (const auto& g : d.cpus) {
    if (g.cpus == "cpu 1") cpu1 = &g;
    if (g.cpus == "cpu 2") cpu2 = &g;
  }
  ASSERT_NE(cpu1, nullptr);
  ASSERT_NE(cpu2, nullptr);
  ASSERT_EQ(cpu1->flags.size(), 2u) << allocation_text(d);
  EXPECT_NE(cpu1->flags[0].find("same priority 40 on cpu 1"), std::string::npos) << cpu1->flags[0];
  EXPECT_NE(cpu1->flags[1].find("consumer above its producer on cpu 1: 'mon' (data p45) reads 'gen' (data p40)"),
            std::string::npos)
      << cpu1->flags[1];
  EXPECT_TRUE(cpu2->flags.empty());
  EXPECT_EQ(cpu1->tasks.front().priority, 45);  // highest first
}

TEST(DeploymentTest, PartitionedHostPlacesUnpinnedRtTasksOnItsRtCpus) {
  const Deployment d = build(
      {read_host_text("host: p\ncpus: {rt: \"2-3\", housekeeping: 0}\ncomponents:\n"
                      "  - {name: g, class: Generator, data_task: {priority: 80, period_ms: 1}}\n"
                      "  - {name: n, class: Generator, instance: 1, data_task: {priority: 0, period_ms: 1}}\n",
                      "p.yaml")});
  ASSERT_TRUE(d.hosts[0].errors.empty()) << errors_of(d.hosts[0]);
  EXPECT_EQ(d.hosts[0].rt_cpus, (std::vector<int>{2, 3}));
  // Both command tasks (priority 30) and g's data task on the rt cpus; n's data task
  // (priority 0) is not an RT task.
  ASSERT_EQ(d.cpus.size(), 1u);
  EXPECT_EQ(d.cpus[0].cpus, "rt cpus 2,3");
  EXPECT_EQ(d.cpus[0].tasks.size(), 3u);
}

TEST(DeploymentTest, ErrorsCarryFileLineColumnAndTheRestIsRead) {
  const Host h = read_host_text(
      "host: a\ncomponents:\n  - {name: g, class: Generator, data_task: {priority: 120}}\n"
      "  - {name: m, class: Monitor}\n",
      "bad.yaml");
  ASSERT_EQ(h.errors.size(), 1u);
  EXPECT_EQ(h.errors[0].str(), "bad.yaml:3:55: 'priority' must be an integer 0..99");
  EXPECT_EQ(h.components.size(), 2u);
  const Host syntax = read_host_text("host: [a\n", "s.yaml");
  ASSERT_EQ(syntax.errors.size(), 1u);
  EXPECT_EQ(syntax.errors[0].line, 2);
}

TEST(DeploymentTest, DuplicateAddressesAcrossFilesAreProblems) {
  const Deployment d = build({read_host_text(kAux, "aux.yaml"), read_host_text(kAux, "copy.yaml")});
  ASSERT_EQ(d.problems.size(), 2u);  // the host name and the address
  EXPECT_NE(d.problems[1].find("copy.yaml:8:5: component 'scanner' has the address Generator(1/0)"), std::string::npos)
      << d.problems[1];
}

TEST(DeploymentTest, LiveMarksStaleHostsAndMeasurements) {
  const Deployment d = fleet();
  Live live;
  live.hosts.resize(d.hosts.size());
  live.tasks.resize(d.hosts.size());
  for (std::size_t h = 0; h < d.hosts.size(); ++h) live.tasks[h].resize(d.hosts[h].components.size());
  live.hosts[0].answered = true;
  live.tasks[0][0] = {true, "ENABLED", 0.125, 42'000, 1'250'000, 10'000'000};
  const std::string dot = to_dot(d, &live);
  EXPECT_NE(dot.find("ENABLED, util 12.5%, worst wake-up 42 us"), std::string::npos) << dot;
  EXPECT_NE(dot.find("STALE: did not answer discovery"), std::string::npos) << dot;
  const std::string text = allocation_text(d, &live);
  EXPECT_NE(text.find("12.5%"), std::string::npos) << text;
  EXPECT_NE(text.find("r1-main (main.yaml, system 1)  STALE"), std::string::npos) << text;
}

// Live flows (GET_LISTENERS): a file's flow whose producer lists its consumer runs;
// one whose producer answered without it does not; a listener no file places (a tool)
// is a live-only flow to a box of its own; a reply that does not add up is refused.
TEST(DeploymentTest, LiveFlowsFromListenersAreMatchedWithTheFiles) {
  // The classes as rackd lists them, with their TiMS class ids (this program knows no
  // class names: the addresses come from the ids alone, as for a plug-in's).
  const std::vector<ClassInfo> classes{{"Generator", "Generator", true, {}, 0x40},
                                       {"Monitor", "Monitor", true, {"source"}, 0x41}};
  const Deployment d = build({read_host_text(R"Y(host: h
system: 0
components:
  - {name: gen, class: Generator, instance: 0, data_task: {priority: 60, period_ms: 10}}
  - {name: mon, class: Monitor, instance: 0, params: {source: gen}}
  - {name: idle, class: Monitor, instance: 1, params: {source: gen}}
)Y",
                                             "h.yaml")},
                             &classes);
  EXPECT_EQ(d.hosts[0].components[1].address_text, "Monitor(0/0)");
  ASSERT_EQ(d.flows.size(), 2u);
  wire::ListenersReply r;
  r.data_task = 1;
  r.count = r.total = 2;
  r.period_ns = 10'000'000;
  r.mailbox[0] = tims::Address::make(0, class_ids::kMonitor, 0, 3).raw();
  r.factor[0] = 10;
  r.listener_period_ns[0] = 100'000'000;
  r.mailbox[1] = tims::Address::make(255, tims::classes::kTool, 4, 1).raw();
  r.factor[1] = 5;
  r.listener_period_ns[1] = 50'000'000;
  Live live;
  ASSERT_EQ(add_listeners(d, 0, 0, std::as_bytes(std::span(&r, 1)), true, live), nullptr);
  match_live_flows(d, live);
  ASSERT_EQ(live.flows.size(), 2u);
  const std::size_t mon = d.flows[0].consumer == 1 ? 0 : 1;
  EXPECT_EQ(live.flow_state[mon], 1) << "mon subscribes";
  EXPECT_EQ(live.flow_state[1 - mon], 0) << "idle does not";
  EXPECT_EQ(live.flows[0].flow, mon);
  EXPECT_EQ(live.flows[0].consumer, 1u);
  EXPECT_EQ(live.flows[1].flow, kNone);
  EXPECT_EQ(live.flows[1].consumer, kNone);
  EXPECT_EQ(listener_text(d, live.flows[0]).rfind("mon (", 0), 0u) << listener_text(d, live.flows[0]);
  const std::string dot = to_dot(d, &live);
  EXPECT_NE(dot.find("source, 10 ms\\nrunning"), std::string::npos) << dot;
  EXPECT_NE(dot.find("source, 10 ms\\nnot running\", color=grey, fontcolor=grey, style=dotted"), std::string::npos)
      << dot;
  EXPECT_NE(dot.find("c0_0 -> l_0 [label=\"live only, 50 ms\""), std::string::npos) << dot;
  const std::string json = to_json(d, &live);
  EXPECT_NE(json.find("\"running\":true"), std::string::npos) << json;
  EXPECT_NE(json.find("\"running\":false"), std::string::npos) << json;
  EXPECT_NE(json.find("\"consumer\":null,\"consumer_host\":null,\"period_ns\":50000000,\"in_files\":false"),
            std::string::npos)
      << json;

  // A producer not asked: its flows are unknown, neither running nor not.
  Live none;
  match_live_flows(d, none);
  EXPECT_EQ(none.flow_state, (std::vector<int>{-1, -1}));
  EXPECT_EQ(to_json(d, &none).find("\"running\":false"), std::string::npos);

  r.factor[1] = 0;
  Live bad;
  const char* why = add_listeners(d, 0, 0, std::as_bytes(std::span(&r, 1)), true, bad);
  ASSERT_NE(why, nullptr);
  EXPECT_STREQ(why, "a listener's factor is 0");
  EXPECT_TRUE(bad.flows.empty());
  EXPECT_NE(add_listeners(d, 0, 7, std::as_bytes(std::span(&r, 1)), true, bad), nullptr) << "no component 7";
}

// A TASKS reply (GET_TASKS) as a rackd's component sends it: the host file's priority
// and cpu, the kernel's reading (SCHED_FIFO at `prio` on `cpu`, or on CPUs 0 and 1),
// the host's one network.
wire::TasksReply tasks_reply(int cmd_prio, int data_prio, int cpu, int64_t period_ns, bool data = true) {
  wire::TasksReply r;
  r.data_task = static_cast<uint8_t>(data ? (period_ns > 0 ? 1 : 2) : 0);
  r.task_count = static_cast<uint8_t>(data ? 2 : 1);
  r.online_cpus = 2;
  for (std::size_t i = 0; i < r.task_count; ++i) {
    const int prio = i == 0 ? cmd_prio : data_prio;
    r.measured[i] = wire::kTaskMeasured;
    r.policy[i] = 1;  // SCHED_FIFO
    r.priority[i] = prio;
    r.configured_priority[i] = prio;
    r.configured_cpu[i] = i == 1 ? cpu : -1;
    r.last_cpu[i] = 0;
    r.affinity[i * wire::kTaskCpuWords] = i == 1 && cpu >= 0 ? uint64_t{1} << cpu : 3u;  // else CPUs 0 and 1
  }
  if (data) {
    r.period_ns[1] = period_ns;
    r.measured_period_ns[1] = period_ns > 0 ? period_ns + 20'000 : 30'000'000;
  }
  r.network_count = 1;
  std::memcpy(r.network_name, "robot", 6);
  std::memcpy(r.network_url, "udpm://239.255.76.67:7667?ttl=0", 32);
  return r;
}

// Discovery alone (no host file): two hosts of one robot, their tasks as GET_TASKS
// says they run and their flows from GET_LISTENERS: the cross-host flow crosses the
// robot's network, the local one none; the allocation per CPU with its inversions
// (a consumer above its producer, two data tasks with one priority) comes from what runs.
TEST(DeploymentTest, AdoptRunningTakesTasksFlowsAndNetworksFromWhatRuns) {
  const auto discovered = [](const char* name, int host_id, std::vector<std::pair<const char*, uint8_t>> comps) {
    Host h;
    h.file = "discovery on test";
    h.host = name;
    h.system = 1;
    h.host_id = host_id;
    h.tasks_known = false;
    uint8_t instance = 0;
    for (const auto& [cname, cls] : comps) {
      Component c;
      c.name = cname;
      c.impl = cls == class_ids::kMonitor ? "Monitor" : "Generator";
      c.class_name = c.impl;
      c.instance = instance;
      c.address = tims::Address::make(1, cls, instance, 0).raw();
      c.address_text = c.impl + "(1/" + std::to_string(instance) + ")";
      c.command_task.priority = -1;  // not known (cpu: -1)
      c.data_task.priority = -1;
      h.components.push_back(c);
      ++instance;
    }
    return h;
  };
  Deployment d = build(
      {discovered("alpha", 0, {{"src", class_ids::kGenerator}}),
       discovered("beta", 1,
                  {{"mon", class_ids::kMonitor}, {"g2", class_ids::kGenerator}, {"m2", class_ids::kMonitor}})});
  // g2 is Generator(1/1), m2 Monitor(1/2) on beta; src Generator(1/0) on alpha.
  ASSERT_TRUE(d.flows.empty());
  Live live;
  live.tasks.resize(2);
  live.tasks[0].resize(1);
  live.tasks[1].resize(3);
  const auto add = [&](std::size_t h, std::size_t c, const wire::TasksReply& r) {
    const char* bad = add_tasks(d, h, c, std::as_bytes(std::span(&r, 1)), true, live);
    EXPECT_EQ(bad, nullptr) << bad;
  };
  add(0, 0, tasks_reply(30, 60, 0, 10'000'000));
  add(1, 0, tasks_reply(25, 50, 0, 0));
  add(1, 1, tasks_reply(25, 50, 0, 20'000'000));
  add(1, 2, tasks_reply(25, 55, 0, 0));
  EXPECT_EQ(live.tasks[0][0].data.cpus, (std::vector<int>{0}));
  EXPECT_EQ(live.tasks[0][0].command.cpus, (std::vector<int>{0, 1}));
  EXPECT_EQ(live.tasks[0][0].data.policy, "SCHED_FIFO");
  // src -> mon (every 2nd sample), g2 -> m2.
  const auto listeners = [&](std::size_t h, std::size_t c, uint32_t mailbox, int64_t period) {
    wire::ListenersReply r;
    r.data_task = 1;
    r.count = r.total = 1;
    r.period_ns = period;
    r.mailbox[0] = mailbox;
    r.factor[0] = 1;
    r.listener_period_ns[0] = period;
    EXPECT_EQ(add_listeners(d, h, c, std::as_bytes(std::span(&r, 1)), true, live), nullptr);
  };
  listeners(0, 0, tims::Address::make(1, class_ids::kMonitor, 0, 3).raw(), 20'000'000);
  listeners(1, 1, tims::Address::make(1, class_ids::kMonitor, 2, 3).raw(), 20'000'000);
  match_live_flows(d, live);
  adopt_running(d, live);

  EXPECT_TRUE(d.hosts[0].tasks_known);
  EXPECT_EQ(d.hosts[1].components[2].data_task.priority, 55);
  EXPECT_EQ(d.hosts[1].components[2].data_task.cpu, 0);
  EXPECT_EQ(d.hosts[1].components[2].command_task.cpu, -1) << "CPUs 0 and 1 of 2: any";
  ASSERT_EQ(d.hosts[0].networks.size(), 1u);
  EXPECT_EQ(d.hosts[0].networks[0].name, "robot");
  ASSERT_EQ(d.flows.size(), 2u);
  EXPECT_TRUE(d.flows[0].live);
  EXPECT_EQ(d.flows[0].producer_host, 0u);
  EXPECT_EQ(d.flows[0].consumer_host, 1u);
  EXPECT_EQ(d.flows[0].period_ns, 20'000'000);
  EXPECT_EQ(d.flows[0].networks, (std::vector<std::string>{"robot"})) << "alpha -> beta over the robot's bus";
  EXPECT_TRUE(d.flows[1].networks.empty()) << "g2 -> m2 stays inside beta";
  EXPECT_EQ(live.flow_state, (std::vector<int>{1, 1}));

  const std::string alloc = allocation_text(d, &live);
  EXPECT_NE(alloc.find("  cpu 0\n"), std::string::npos) << alloc;
  EXPECT_NE(alloc.find("    60   src                  data  10 ms      10.0 ms"), std::string::npos) << alloc;
  EXPECT_NE(alloc.find("! same priority 50 on cpu 0: data tasks of 'mon' and 'g2'"), std::string::npos) << alloc;
  EXPECT_NE(alloc.find("! consumer above its producer on cpu 0: 'm2' (data p55) reads 'g2' (data p50) through a "
                       "running subscription"),
            std::string::npos)
      << alloc;
  EXPECT_EQ(alloc.find("not known"), std::string::npos) << alloc;
  EXPECT_EQ(alloc.find("its host file asks"), std::string::npos) << alloc;
  const std::string json = to_json(d, &live);
  EXPECT_NE(json.find(R"("networks":["robot"],"running":true,"live":true})"), std::string::npos) << json;
  EXPECT_NE(json.find(R"("consumer":"mon","consumer_host":"beta","period_ns":20000000,"in_files":false})"),
            std::string::npos)
      << json;
  EXPECT_NE(json.find(R"("data_task":{"priority":60,"cpu":0,"period_ns":10000000})"), std::string::npos) << json;
  const std::string dot = to_dot(d, &live);
  EXPECT_NE(dot.find("subscribed, 20 ms\\nvia robot\\nrunning"), std::string::npos) << dot;
  EXPECT_NE(dot.find("runs every 10.0 ms"), std::string::npos) << dot;

  // A task that fell back to normal scheduling is listed and flagged.
  wire::TasksReply fallback = tasks_reply(25, 50, 0, 0);
  fallback.policy[1] = 0;
  fallback.priority[1] = 0;
  Deployment d2 = build({discovered("gamma", 2, {{"mon", class_ids::kMonitor}})});
  Live l2;
  ASSERT_EQ(add_tasks(d2, 0, 0, std::as_bytes(std::span(&fallback, 1)), true, l2), nullptr);
  match_live_flows(d2, l2);
  adopt_running(d2, l2);
  const std::string a2 = allocation_text(d2, &l2);
  EXPECT_NE(a2.find("! 'mon' data task runs at priority 0 (normal scheduling), its host file asks for 50"),
            std::string::npos)
      << a2;
}

// The TASKS decoder: what does not add up is refused with the reason; a later version
// with appended fields is read by its version-1 part.
TEST(DeploymentTest, TasksReplyDecoderRefusesWhatDoesNotAddUp) {
  const wire::TasksReply good = tasks_reply(30, 60, 1, 10'000'000);
  const auto decode = [](const wire::TasksReply& r) -> std::string {
    wire::TasksReply out;
    const char* bad = wire::decode_tasks(std::as_bytes(std::span(&r, 1)), true, out);
    return bad == nullptr ? "" : bad;
  };
  EXPECT_EQ(decode(good), "");
  wire::TasksReply b = good;
  b.task_count = 1;
  EXPECT_EQ(decode(b), "task_count is not 1 without a data task, 2 with one");
  b = good;
  b.priority[1] = 0;
  EXPECT_EQ(decode(b), "a priority does not go with its policy");
  b = good;
  b.affinity[4] = 0;
  EXPECT_EQ(decode(b), "a task may run on no CPU");
  b = good;
  b.network_name[5] = 'x';
  std::memset(b.network_name, 'x', wire::kTaskNetworkNameLen);
  EXPECT_EQ(decode(b), "a network's name is empty, unterminated or not printable");
  b = good;
  b.version = 0;
  EXPECT_EQ(decode(b), "version is 0");
  b = good;
  b.period_ns[0] = 5;
  EXPECT_EQ(decode(b), "the command task has a period");
  // Version 2 with 8 more bytes: its version-1 part is used; version 1 must be exact.
  std::vector<std::byte> longer(sizeof(wire::TasksReply) + 8);
  b = good;
  b.version = 2;
  std::memcpy(longer.data(), &b, sizeof b);
  wire::TasksReply out;
  EXPECT_EQ(wire::decode_tasks(longer, true, out), nullptr);
  EXPECT_EQ(out.priority[1], 60);
  std::memcpy(longer.data(), &good, sizeof good);
  EXPECT_STREQ(wire::decode_tasks(longer, true, out), "a version-1 TASKS reply is 680 bytes");
  EXPECT_NE(wire::decode_tasks(std::span(longer).first(100), true, out), nullptr);
  // The other byte order: swapped fields come back.
  wire::TasksReply swapped = good;
  tims::swap_fields(tims::fields_of<wire::TasksReply>, reinterpret_cast<std::byte*>(&swapped), sizeof swapped);
  ASSERT_EQ(wire::decode_tasks(std::as_bytes(std::span(&swapped, 1)), false, out), nullptr);
  EXPECT_EQ(out.period_ns[1], 10'000'000);
  EXPECT_EQ(out.affinity[4], 2u);
}

TEST(DeploymentTest, HostileTextNeverThrows) {
  for (const char* text : {"", "\xff\xfe", "&a [*a]", "components: &c [*c]", "components: [{params: &p {a: *p}}]",
                           "cpus: {rt: \"3-1\"}", "components: [{data_task: {period_ms: -1}}]", "- a\n- b"}) {
    const Host h = read_host_text(text, "x.yaml");
    const Deployment d = build({h});
    (void)to_dot(d);
    (void)to_json(d);
    (void)allocation_text(d);
  }
  EXPECT_FALSE(read_host_text("cpus: {rt: \"3-1\"}", "x.yaml").errors.empty());
}

}  // namespace
}  // namespace rack::deploy
