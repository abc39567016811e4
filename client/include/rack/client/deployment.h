// A deployment as the tools see it (issue 25): a set of host files read without the
// executor, the data flows between their components, and the allocation of their RT
// tasks per CPU. `rackctl graph` and `rackctl alloc` print it (DOT, text, JSON); the
// live view adds what discovery and the components report (stale hosts; GET_STATS:
// utilisation, worst wake-up latency; GET_LISTENERS: the flows that run; GET_TASKS:
// each task's priority, CPUs and period as it runs, the hosts' networks). Without
// host files (adopt_running) the deployment is what runs.
//
// The reader is lenient where `rackd --check` is strict: it reads what a picture
// needs (host, system, host_id, role, networks, cpus, each component's name, class,
// instance, tasks and parameters) and records every problem it meets as a
// file:line:col error beside what it could read. Whether a file is valid is rackd's
// loader's answer (rackd --check); this one never needs the component classes.
//
// Flows offline: a component's parameter that its class declares as a component
// reference (ClassInfo, from `rackd --list-classes --json`), whose value names another
// component of the same host file or is an address like Generator(1/0) (the forms
// rackd resolves), is a flow from that component (the producer) to this one (the
// consumer). Without the class's description any parameter with such a value counts
// (a guess: a choice that happens to be a component's name is taken for a flow). An address that no given host
// file places is drawn as an unplaced producer. An address names a component when
// system and instance match and its class is the component's: TiMS' name of the
// class (the longest registered class name that begins the implementation's,
// ChassisSim: Chassis; a program knows the classes its registry added),
// else any implementation that begins with the address's class name. A component
// whose class TiMS does not know has no numeric address offline (address_text ends
// in '?', and the live view cannot ask it for statistics).
//
// Decodes outside input: never throws for any bytes; every problem is an error.
// Real-time contract: not RT-safe (tools only).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "rack/client/host_file.h"

namespace rack::deploy {

inline constexpr std::size_t kNone = static_cast<std::size_t>(-1);
inline constexpr std::size_t kMaxComponentsPerHost = 4096;

struct Task {
  int priority = 0;  // 1..99 SCHED_FIFO, 0 normal scheduling, -1 not known (Host::tasks_known)
  int cpu = -1;      // -1: not pinned (the host's rt cpus, else any)
  int line = 0;      // where the file gives it (0: the default)
  int column = 0;
  // A task as it runs (adopt_running): the CPUs it may run on when that is neither
  // one CPU (cpu) nor every CPU (empty), and the priority its host file asked for when
  // that is not the one it runs at (-1: the same, or not known).
  std::vector<int> cpus{};
  int configured_priority = -1;
};

struct Param {
  std::string key;
  std::string value;  // a scalar's text ("" for a list or map)
  int line = 0;
  int column = 0;
};

struct Component {
  std::string name;
  std::string impl;        // the host file's class ("ChassisSim")
  std::string class_name;  // the addresses' class ("Chassis"); "" when unknown offline
  int instance = 0;
  std::optional<uint32_t> address;  // raw TiMS address of the command mailbox, when known
  std::string address_text;         // "Chassis(1/0)", or "ChassisSim(1/0)?" when unknown
  Task command_task{30, -1};
  Task data_task{40, -1};
  bool has_data_task = false;  // the file gives a data_task
  int64_t period_ns = 0;       // data_task.period_ms (0: triggered or none)
  std::vector<Param> params;
  int line = 0;
  int column = 0;
};

struct Network {
  std::string name;
  std::string url;
  std::string scope;  // host | robot | fleet ("" when not given)
};

struct Host {
  std::string file;
  std::string host;  // "" when the file gives none (rackd takes the machine's)
  int system = 0;
  int host_id = 0;
  std::string role = "executor";
  std::vector<Network> networks;  // empty: one network, lcm_url (or LCM's default)
  std::string lcm_url;
  // false: a host found by discovery without its host file (rackctl graph/alloc --live
  // with no FILE) until adopt_running() takes its tasks as they run: a task of priority
  // -1 is drawn and listed as not known rather than as the defaults.
  bool tasks_known = true;
  std::vector<int> rt_cpus;  // the `cpus:` partitioning (empty: none)
  std::vector<int> housekeeping_cpus;
  std::vector<Component> components;
  std::vector<ConfigError> errors;          // what the reader met (file:line:col)
  [[nodiscard]] std::string label() const;  // host, else the file's name
};

// Reads one host file's text; `file` names it in errors (the fuzz harnesses' entry).
[[nodiscard]] Host read_host_text(const std::string& text, const std::string& file);
// Reads a file (read_host_bytes' rules: regular, at most kMaxHostFileBytes).
[[nodiscard]] Host read_host(const std::string& path);
// The host files a command line names: files as given, directories as their *.yaml
// and *.yml files (sorted; not recursive). An unreadable argument is an error.
[[nodiscard]] std::vector<std::string> host_file_paths(const std::vector<std::string>& args,
                                                       std::vector<std::string>& errors);

struct Flow {
  std::size_t consumer_host = 0;
  std::size_t consumer = 0;
  std::size_t producer_host = kNone;  // kNone: not placed by any given host file
  std::size_t producer = kNone;
  std::string target;                 // the parameter's value ("Generator(1/0)", "scanner")
  std::string param;                  // the consumer's parameter ("source")
  int64_t period_ns = 0;              // the producer's data period (0: triggered or unknown)
  std::vector<std::string> networks;  // empty: inside one host; else the networks it crosses
  int line = 0;
  int column = 0;
  // A running subscription taken as a flow (adopt_running: no host file declares it);
  // param is "" then and period_ns what the listener gets.
  bool live = false;
};

// One RT task on a CPU of a host (a CPU group: "cpu 2", "rt cpus 2,3", "any").
struct PlacedTask {
  std::size_t host = 0;
  std::size_t component = 0;
  bool data = true;  // the data task; false: the command task
  int priority = 0;
  int64_t period_ns = 0;
};

struct CpuGroup {
  std::size_t host = 0;
  std::string cpus;                // "cpu 2" | "rt cpus 2,3" | "any cpu"
  std::vector<PlacedTask> tasks;   // highest priority first
  std::vector<std::string> flags;  // configuration priority inversions, in words
};

struct Deployment {
  std::vector<Host> hosts;
  std::vector<Flow> flows;
  std::vector<CpuGroup> cpus;
  std::vector<std::string> problems;  // across files: duplicate hosts or addresses
};

// What a class says of itself (`rackd --list-classes --json`, or GET_CLASS): with it
// a flow is exactly a parameter the class declares as a component reference, and the
// address's class is the class's own (ChassisSim: Chassis).
struct ClassInfo {
  std::string impl;               // "ChassisSim"
  std::string class_name;         // "Chassis"
  bool described = false;         // parameters known; false: a plug-in by its manifest
  std::vector<std::string> refs;  // its parameters that name a component
  int class_id = -1;              // its TiMS class id (a plug-in's: TiMS here may not know it); -1 unknown
};

// Flows, networks crossed and the allocation of a set of hosts. Without `classes` (or
// for a class they do not describe) a flow is any parameter whose value names a
// component or is an address (see above).
[[nodiscard]] Deployment build(std::vector<Host> hosts, const std::vector<ClassInfo>* classes = nullptr);

// What the live view knows of a host and its components (rackctl graph --live).
struct LiveHost {
  bool answered = false;     // announced within the discovery window
  int64_t seen_ms_ago = -1;  // -1: never
};
// One task as it runs (GET_TASKS, wire::TasksReply; add_tasks).
struct RunningTask {
  bool measured = false;           // the kernel's reading came with the reply
  std::string policy;              // SCHED_FIFO, SCHED_OTHER, ... ("" not measured)
  int priority = -1;               // as it runs: 1..99 FIFO/RR, 0 otherwise; -1 not measured
  std::vector<int> cpus;           // the CPUs it may run on (empty: not measured)
  int last_cpu = -1;               // the one it ran on last
  int configured_priority = -1;    // what its host file asked for
  int configured_cpu = -1;         // -1: not pinned
  int64_t period_ns = 0;           // the timer's period (a periodic data task), else 0
  int64_t measured_period_ns = 0;  // the mean interval between its loop() runs lately (0: unknown)
};
struct LiveTask {
  bool answered = false;
  std::string state;              // ENABLED | DISABLED | ERROR | NOT_AVAILABLE | no reply
  double utilisation = -1.0;      // execution p50 / period (0..), -1 unknown
  int64_t worst_latency_ns = -1;  // the data task's worst wake-up latency, -1 unknown
  int64_t exec_p50_ns = -1;
  int64_t period_ns = 0;
  // GET_TASKS (add_tasks): how its tasks run and its host's networks; false: not
  // asked, or no usable answer (an older rackd answers ERROR).
  bool tasks_known = false;
  bool has_data_task = false;
  RunningTask command{}, data{};
  int online_cpus = 0;              // CPUs of its host (0: not measured)
  std::vector<Network> networks{};  // its host's TiMS networks
};
// A subscription that runs (a producer's GET_LISTENERS, wire::ListenersReply): the
// live data flow from producer to listener, whatever the host files say.
struct LiveFlow {
  std::size_t producer_host = 0;  // in Deployment::hosts
  std::size_t producer = 0;
  uint32_t listener = 0;              // raw TiMS address of the mailbox the samples go to
  std::size_t consumer_host = kNone;  // the component that mailbox belongs to, when a host places it
  std::size_t consumer = kNone;
  int64_t period_ns = 0;     // what the listener gets (0: unknown, a triggered producer)
  std::size_t flow = kNone;  // the Deployment::flows entry it is; kNone: not in the host files
};
struct Live {
  std::vector<LiveHost> hosts;               // per Deployment::hosts
  std::vector<std::vector<LiveTask>> tasks;  // per host, per component
  std::vector<LiveFlow> flows;               // every listener the producers reported
  // Per host, per component: its GET_LISTENERS answered (so a flow from it that is
  // not among `flows` does not run now); false: not asked, or no usable answer.
  std::vector<std::vector<bool>> listeners_known;
  // Per Deployment::flows (after match_live_flows): 1 runs now, 0 does not (its
  // producer answered GET_LISTENERS without it), -1 unknown.
  std::vector<int> flow_state;
};

// Adds the listeners of the component `c` of host `h` from its LISTENERS reply body
// (`native`: the body's byte order is this host's): nullptr, or what is wrong with the
// body (wire::decode_listeners; then nothing is added). Decodes outside input.
[[nodiscard]] const char* add_listeners(const Deployment& d, std::size_t h, std::size_t c,
                                        std::span<const std::byte> body, bool native, Live& live);
// Takes the TASKS reply body of the component `c` of host `h` (GET_TASKS,
// wire::TasksReply) into live.tasks[h][c]: nullptr, or what is wrong with the body
// (wire::decode_tasks; then nothing changes). Decodes outside input.
[[nodiscard]] const char* add_tasks(const Deployment& d, std::size_t h, std::size_t c, std::span<const std::byte> body,
                                    bool native, Live& live);
// The deployment as it runs, for hosts found by discovery without their host file
// (Host::tasks_known false; rackctl graph/alloc --live with no FILE): each component
// whose GET_TASKS answered gets its tasks' priorities and CPUs as they run (a task the
// kernel has not been asked about yet: as its host file asked), its data task and
// period; its host gets its networks. Every running subscription between two placed
// components that no flow declares becomes a Flow (live, the listener's period, the
// networks it crosses), and the allocation with its flags is made again from these.
// Call after match_live_flows(); hosts read from files keep their files' values.
void adopt_running(Deployment& d, Live& live);
// Names the consumer of every live flow (the component whose address the listener's
// mailbox is on) and matches live flows with the host files' flows (the same producer
// and consumer): sets LiveFlow::flow and Live::flow_state.
void match_live_flows(const Deployment& d, Live& live);
// The text of a listener's mailbox: the component's name when a host places it
// ("monitor (Monitor(0/0)#3)"), else its address ("Tool(255/4)#1").
[[nodiscard]] std::string listener_text(const Deployment& d, const LiveFlow& f);

// Graphviz DOT: a cluster per system (robot) and host, a node per component (class,
// address, tasks), an edge per flow (parameter, period, networks crossed); errors in
// red, unplaced producers dashed, stale hosts (live: did not answer) grey and dashed.
// Live: a file's flow that does not run now is grey and dotted ("not running"); a
// running flow no host file declares is green ("live only", with the listener's
// period), to a box for its listener when no host places it (a tool's watch).
[[nodiscard]] std::string to_dot(const Deployment& d, const Live* live = nullptr);
// The allocation per CPU of each host as a table, flags included.
[[nodiscard]] std::string allocation_text(const Deployment& d, const Live* live = nullptr);
// The whole deployment as one JSON object (hosts, components, flows, cpus, errors).
[[nodiscard]] std::string to_json(const Deployment& d, const Live* live = nullptr);

}  // namespace rack::deploy
