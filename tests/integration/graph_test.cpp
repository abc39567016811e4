// Integration: rackctl graph and alloc (issue 25): a deployment from its host files
// offline (configs/two_robots/), priority inversions flagged, reader errors at their
// file:line:col, and the live view against a real rackd on a private bus (its
// components' state, utilisation and worst wake-up latency; a host that does not
// answer marked stale).
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kConfigs = RACK_CONFIGS_DIR;

TEST(GraphTest, TwoRobotsOfflineAsDot) {
  Watchdog watchdog(30s, "GraphTest");
  const RunResult r = run({kRackctl, "graph", kConfigs + "/two_robots/"}, 20s);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.rfind("digraph deployment {", 0), 0u) << r.out;
  // Robot 1's producer feeds a consumer on its own bus and one on robot 2 across the
  // fleet link (through both system routers).
  EXPECT_NE(r.out.find("label=\"source, 10 ms\\nvia robot1\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("label=\"source, 10 ms\\nvia robot1 > fleet > robot2\""), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("base-station (top_router, host_id 0)"), std::string::npos) << r.out;
  const RunResult j = run({kRackctl, "graph", "--format", "json", kConfigs + "/two_robots/"}, 20s);
  ASSERT_EQ(j.exit_code, 0) << j.err;
  EXPECT_NE(j.out.find("\"networks\":[\"robot1\",\"fleet\",\"robot2\"]"), std::string::npos) << j.out;
}

TEST(GraphTest, AllocFlagsInversionsAndReportsErrorsAtTheirLine) {
  Watchdog watchdog(30s, "GraphTest");
  TempDir dir;
  const auto file = dir.write(
      "host.yaml",
      "host: inv\n"
      "components:\n"
      "  - {name: gen, class: Generator, data_task: {priority: 40, period_ms: 5, cpu: 0}}\n"
      "  - {name: mon, class: Monitor, data_task: {priority: 45, cpu: 0}, params: {source: gen}}\n");
  const RunResult r = run({kRackctl, "alloc", file.string()}, 20s);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("  cpu 0\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("! consumer above its producer on cpu 0: 'mon' (data p45) reads 'gen' (data p40)"),
            std::string::npos)
      << r.out;
  const auto bad = dir.write("bad.yaml",
                             "host: bad\ncomponents:\n  - {name: g, class: Generator, data_task: {priority: x}}\n");
  const RunResult e = run({kRackctl, "graph", bad.string()}, 20s);
  EXPECT_EQ(e.exit_code, 1);
  EXPECT_NE(e.err.find(bad.string() + ":3:55: 'priority' must be an integer 0..99"), std::string::npos) << e.err;
  EXPECT_NE(e.out.find("color=red"), std::string::npos) << e.out;  // the host drawn as faulty
  const RunResult missing = run({kRackctl, "graph", (dir.path() / "nothing.yaml").string()}, 20s);
  EXPECT_EQ(missing.exit_code, 2) << missing.err;
}

TEST(GraphTest, LiveShowsMeasurementsAndStaleHosts) {
  Watchdog watchdog(60s, "GraphTest");
  LcmBus bus;
  TempDir dir;
  Process rackd({kRackd, kConfigs + "/demo.yaml", "--lcm", bus.url()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  // A second host in the deployment that never runs.
  const auto absent = dir.write("absent.yaml",
                                "host: absent\nsystem: 7\ncomponents:\n"
                                "  - {name: far, class: Monitor, params: {source: \"Generator(0/0)\"}}\n");
  // The demo's monitor switches the generator on; wait until it has run cycles.
  std::string out;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    const RunResult r = run({kRackctl, "--lcm", bus.url(), "--discover-ms", "1500", "alloc", "--live",
                             kConfigs + "/demo.yaml", absent.string()},
                            30s);
    ASSERT_EQ(r.exit_code, 0) << r.err;
    out = r.out;
    if (out.find("ENABLED") != std::string::npos && out.find(" us ") != std::string::npos) break;
    std::this_thread::sleep_for(300ms);
  }
  EXPECT_NE(out.find("absent (" + absent.string() + ", system 7)  STALE: did not answer discovery"), std::string::npos)
      << out;
  EXPECT_EQ(out.find("demo (" + kConfigs + "/demo.yaml, system 0)  STALE"), std::string::npos) << out;
  // The generator's data task: period 10 ms, a utilisation and a worst wake-up latency.
  EXPECT_NE(out.find("generator            data  10 ms      "), std::string::npos) << out;
  const auto gen = out.find("generator            data");
  ASSERT_NE(gen, std::string::npos) << out;
  const std::string row = out.substr(gen, out.find('\n', gen) - gen);
  EXPECT_NE(row.find('%'), std::string::npos) << row;
  EXPECT_NE(row.find(" us "), std::string::npos) << row;
  EXPECT_NE(row.find("ENABLED"), std::string::npos) << row;
  const RunResult g = run({kRackctl, "--lcm", bus.url(), "--discover-ms", "1500", "graph", "--live",
                           kConfigs + "/demo.yaml", absent.string()},
                          30s);
  ASSERT_EQ(g.exit_code, 0) << g.err;
  EXPECT_NE(g.out.find("STALE: did not answer discovery"), std::string::npos) << g.out;
  EXPECT_NE(g.out.find("ENABLED, util "), std::string::npos) << g.out;
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(30s), std::optional<int>(0)) << rackd.err();
}

// From discovery alone (no host file): two hosts of one robot on one bus, their
// components, the flows that run (GET_LISTENERS) with their periods and the network
// they cross, each task's priority and CPU as it runs (GET_TASKS), and the allocation
// per CPU with the inversions of what runs flagged: all checked against the host
// files the two rackd were started with.
TEST(GraphTest, TwoHostsFromDiscoveryAloneAsTheyRun) {
  Watchdog watchdog(90s, "GraphTest");
  LcmBus bus;
  TempDir dir;
  const auto alpha = dir.write("alpha.yaml",
                               "host: alpha\nsystem: 1\nhost_id: 0\ncomponents:\n"
                               "  - {name: src, class: Generator, instance: 0, autostart: true, "
                               "command_task: {priority: 30}, data_task: {priority: 60, period_ms: 10, cpu: 0}}\n");
  // On beta: a consumer of alpha's src across the bus; a local pair whose consumer is
  // above its producer on CPU 0, and two data tasks at priority 50 on CPU 0.
  const auto beta = dir.write(
      "beta.yaml",
      "host: beta\nsystem: 1\nhost_id: 1\ncomponents:\n"
      "  - {name: mon, class: Monitor, instance: 0, autostart: true, retry_ms: 500, command_task: {priority: 25}, "
      "data_task: {priority: 50, cpu: 0}, params: {source: \"Generator(1/0)\", source_period_ms: 20}}\n"
      "  - {name: g2, class: Generator, instance: 1, autostart: true, command_task: {priority: 25}, "
      "data_task: {priority: 50, period_ms: 20, cpu: 0}}\n"
      "  - {name: m2, class: Monitor, instance: 2, autostart: true, command_task: {priority: 25}, "
      "data_task: {priority: 55, cpu: 0}, params: {source: g2}}\n");
  Process a({kRackd, alpha.string(), "--lcm", bus.url()}, dir.path(), "rackd-alpha");
  ASSERT_TRUE(a.wait_for_stderr("rackd: running", 30s)) << a.err();
  Process b({kRackd, beta.string(), "--lcm", bus.url()}, dir.path(), "rackd-beta");
  ASSERT_TRUE(b.wait_for_stderr("rackd: running", 30s)) << b.err();
  const std::vector<std::string> ctl{kRackctl, "--lcm", bus.url(), "--discover-ms", "1500"};
  const auto rackctl = [&](std::vector<std::string> tail) {
    std::vector<std::string> args = ctl;
    args.insert(args.end(), tail.begin(), tail.end());
    return run(args, 30s);
  };
  // Both subscriptions run and the data tasks' intervals are measured (once a second).
  const std::string
      cross = R"("producer":"src","producer_host":"alpha","period_ns":20000000,"networks":["robot"],"running":true,)"
              R"("live":true})";
  const std::string local = R"("producer":"g2","producer_host":"beta","period_ns":20000000,"networks":[],)"
                            R"("running":true,"live":true})";
  RunResult g;
  const auto deadline = std::chrono::steady_clock::now() + 40s;
  while (std::chrono::steady_clock::now() < deadline) {
    g = rackctl({"graph", "--live", "--format", "json"});
    ASSERT_EQ(g.exit_code, 0) << g.describe();
    if (g.out.find(cross) != std::string::npos && g.out.find(local) != std::string::npos) break;
    std::this_thread::sleep_for(300ms);
  }
  EXPECT_NE(g.out.find(cross), std::string::npos) << "src -> mon over the robot's bus: " << g.out;
  EXPECT_NE(g.out.find(local), std::string::npos) << "g2 -> m2 inside beta: " << g.out;
  EXPECT_NE(g.out.find(R"("consumer":"mon","consumer_host":"beta","param":"")"), std::string::npos) << g.out;
  EXPECT_NE(g.out.find(R"("consumer":"m2","consumer_host":"beta","param":"")"), std::string::npos) << g.out;
  // Every component on every host, with its tasks as they run (the files' values).
  for (const char* want :
       {R"("host":"alpha","system":1,"host_id":0,"role":"executor","networks":[{"name":"robot","scope":"robot",)",
        R"("host":"beta","system":1,"host_id":1,)", R"x("name":"src","impl":"Generator","address":"Generator(1/0)")x",
        R"("command_task":{"priority":30,)", R"("data_task":{"priority":60,"cpu":0,"period_ns":10000000})",
        R"x("name":"mon","impl":"Monitor","address":"Monitor(1/0)")x",
        R"("data_task":{"priority":50,"cpu":0,"period_ns":0})",
        R"("data_task":{"priority":50,"cpu":0,"period_ns":20000000})",
        R"("data_task":{"priority":55,"cpu":0,"period_ns":0})", R"("policy":"SCHED_FIFO","priority":60,"cpus":[0])"}) {
    EXPECT_NE(g.out.find(want), std::string::npos) << want << "\n" << g.out;
  }
  EXPECT_EQ(g.out.find(R"("priority":null)"), std::string::npos) << g.out;
  EXPECT_EQ(g.out.find(R"("answered":false)"), std::string::npos) << g.out;

  // The data task's interval as it runs (measured once a second) follows its period.
  const std::string src_row = "    60   src                  data  10 ms      ";
  RunResult al;
  std::string measured;
  for (const auto until = std::chrono::steady_clock::now() + 15s; std::chrono::steady_clock::now() < until;) {
    al = rackctl({"alloc", "--live"});
    ASSERT_EQ(al.exit_code, 0) << al.describe();
    const auto at = al.out.find(src_row);
    ASSERT_NE(at, std::string::npos) << al.out;
    measured = al.out.substr(at + src_row.size(), al.out.find('\n', at) - at - src_row.size());
    if (!measured.empty() && measured[0] != '-') break;
    std::this_thread::sleep_for(300ms);
  }
  EXPECT_NE(measured.rfind("-", 0), 0u) << "no measured interval: " << al.out;
  EXPECT_NE(measured.find(" ms "), std::string::npos) << measured;
  EXPECT_NE(measured.find("ENABLED"), std::string::npos) << measured;
  EXPECT_NE(al.out.find("alpha (discovery on "), std::string::npos) << al.out;
  EXPECT_NE(al.out.find("  cpu 0\n"), std::string::npos) << al.out;
  EXPECT_NE(al.out.find("    55   m2                   data  triggered  "), std::string::npos) << al.out;
  EXPECT_NE(al.out.find("! same priority 50 on cpu 0: data tasks of 'mon' and 'g2'"), std::string::npos) << al.out;
  EXPECT_NE(al.out.find("! consumer above its producer on cpu 0: 'm2' (data p55) reads 'g2' (data p50) through a "
                        "running subscription"),
            std::string::npos)
      << al.out;
  EXPECT_EQ(al.out.find("not known"), std::string::npos) << al.out;
  EXPECT_EQ(al.out.find("asks for"), std::string::npos) << "every task runs as configured: " << al.out;
  const RunResult dot = rackctl({"graph", "--live"});
  ASSERT_EQ(dot.exit_code, 0) << dot.describe();
  EXPECT_NE(dot.out.find(R"(subscribed, 20 ms\nvia robot\nrunning)"), std::string::npos) << dot.out;
  EXPECT_NE(dot.out.find(R"(subscribed, 20 ms\nrunning)"), std::string::npos) << dot.out;
  EXPECT_NE(dot.out.find("runs every "), std::string::npos) << dot.out;
  // With the host files: the same flows as the files declare, running.
  const RunResult f = rackctl({"alloc", "--live", alpha.string(), beta.string()});
  ASSERT_EQ(f.exit_code, 0) << f.describe();
  EXPECT_EQ(f.out.find("not known"), std::string::npos) << f.out;
  EXPECT_EQ(f.out.find("asks for"), std::string::npos) << f.out;
  b.signal(SIGTERM);
  EXPECT_EQ(b.wait_exit(30s), std::optional<int>(0)) << b.err();
  a.signal(SIGTERM);
  EXPECT_EQ(a.wait_exit(30s), std::optional<int>(0)) << a.err();
}

// Live flows from the producers' listener tables (GET_LISTENERS): with no host file,
// the demo's own subscription (monitor <- generator, every 10th sample) is drawn from
// what runs; a `rackctl watch` shows up as a flow no file declares while it runs and is
// gone once it ended; with the host file, the file's flow is marked running.
TEST(GraphTest, LiveFlowsComeFromTheRunningSubscriptions) {
  Watchdog watchdog(90s, "GraphTest");
  LcmBus bus;
  TempDir dir;
  Process rackd({kRackd, kConfigs + "/demo.yaml", "--lcm", bus.url()}, dir.path(), "rackd");
  ASSERT_TRUE(rackd.wait_for_stderr("rackd: running", 30s)) << rackd.err();
  auto graph = [&](std::vector<std::string> files, const std::string& format) {
    std::vector<std::string> args{kRackctl, "--lcm",   bus.url(), "--discover-ms", "1000", "graph",
                                  "--live", "--rackd", kRackd,    "--format",      format};
    args.insert(args.end(), files.begin(), files.end());
    return run(args, 30s);
  };
  // The monitor's input mailbox, every 10th sample of the generator's 10 ms.
  const std::string monitor_flow = R"("consumer":"monitor","consumer_host":"demo","period_ns":100000000,)";
  // The monitor subscribes once it and the generator are ENABLED (autostart).
  std::string out;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (std::chrono::steady_clock::now() < deadline) {
    const RunResult r = graph({}, "json");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    out = r.out;
    if (out.find(monitor_flow) != std::string::npos) break;
    std::this_thread::sleep_for(300ms);
  }
  EXPECT_NE(out.find(monitor_flow + R"("in_files":false})"), std::string::npos) << "no host file given: " << out;
  EXPECT_EQ(out.find("Tool(255/"), std::string::npos) << out;

  Process watch({kRackctl, "--lcm", bus.url(), "watch", "--period", "50", "generator"}, dir.path(), "watch");
  ASSERT_TRUE(watch.wait_for_stderr("rackctl: watching", 20s)) << watch.err();
  RunResult r = graph({}, "json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const auto tool = r.out.find(R"({"producer":"generator","producer_host":"demo","listener":"Tool(255/)");
  ASSERT_NE(tool, std::string::npos) << r.out;
  const std::string entry = r.out.substr(tool, r.out.find('}', tool) - tool + 1);
  EXPECT_NE(entry.find(R"("consumer":null,"consumer_host":null,"period_ns":50000000,"in_files":false})"),
            std::string::npos)
      << entry;
  // With the host file: its flow runs; the watch is the one flow it does not declare.
  r = graph({kConfigs + "/demo.yaml"}, "json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(R"("param":"source","target":"generator")"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(R"("networks":[],"running":true,"live":false})"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(monitor_flow + R"("in_files":true})"), std::string::npos) << r.out;
  r = graph({kConfigs + "/demo.yaml"}, "dot");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find(R"(source, 10 ms\nrunning)"), std::string::npos) << r.out;  // DOT: a \n in the label
  EXPECT_NE(r.out.find("live only, 50 ms"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("not in these host files (a tool?)"), std::string::npos) << r.out;

  // The watch ends (STOP_CONT_DATA): its flow is gone, the monitor's stays.
  watch.signal(SIGINT);
  EXPECT_EQ(watch.wait_exit(20s), std::optional<int>(0)) << watch.err();
  r = graph({}, "json");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out.find("Tool(255/"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find(monitor_flow), std::string::npos) << r.out;
  rackd.signal(SIGTERM);
  EXPECT_EQ(rackd.wait_exit(30s), std::optional<int>(0)) << rackd.err();
}

}  // namespace
}  // namespace rack::test
