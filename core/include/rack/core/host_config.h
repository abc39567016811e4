// The host file: which components one rackd runs, with their tasks and parameters.
// See configs/demo.yaml for a commented example of every key.
//
// Loading validates everything before anything starts: unknown keys, wrong types,
// missing or unknown parameters, unknown component classes, duplicate names and
// addresses, priorities outside 1..99 (0..99 for data tasks: 0 is normal scheduling),
// CPUs that are not online, non-positive periods, dependency cycles. Each problem is
// reported as `file:line:col: message`.
//
// The file is outside input and read strictly (README "Running a host" lists the
// rules): a regular file of at most kMaxHostFileBytes (checked with fstat before
// reading; FIFOs and devices are refused), UTF-8 text without NUL bytes or control
// characters (also after YAML escapes), one YAML document, no key twice in a map, at
// most kMaxHostNesting levels and kMaxHostScalarBytes per key or value, every integer
// in its key's range (no wrap-around), every time in milliseconds positive and at
// most kMaxHostMilliseconds, LCM URLs valid (rack/tims/lcm_url.h), expiry_ms at least
// twice announce_ms, names within their lengths and characters, and each component's
// parameters as its class checks them (Component::check_parameters).
//
// Real-time contract: not RT-safe (set-up only).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "rack/core/component.h"
#include "rack/core/registry.h"
// ConfigError, kMaxHostFileBytes, read_host_bytes, read_tool_network (rack_client).
#include "rack/client/host_file.h"
#include "rack/rt/capabilities.h"
#include "rack/rt/modeswitch.h"
#include "rack/tims/access.h"
#include "rack/tims/lcm_transport.h"

namespace rack {

// Limits of a host file (README "Running a host"; configs/demo.yaml).
inline constexpr std::size_t kMaxHostScalarBytes = 4096;    // one key or value (a path fits)
inline constexpr std::size_t kMaxHostNameLength = 63;       // host: letters, digits, . _ -
inline constexpr std::size_t kMaxNameLength = 31;           // component and network names: letters, digits, _ -
inline constexpr std::size_t kMaxChannelLength = 63;        // gdos.channel (LCM's channel name limit)
inline constexpr double kMaxHostMilliseconds = 86'400'000;  // every *_ms key: at most a day

// GDOS on this host (the `gdos:` map of a host file; configs/demo.yaml explains it).
struct GdosSettings {
  gdos::Level level = gdos::kDefaultLevel;  // default gdosLevel of every component here
  enum class Stderr : uint8_t { kAlways, kAuto, kNever };
  Stderr to_stderr = Stderr::kAlways;    // auto: only while no gdos viewer listens
  uint32_t ring = 256;                   // records per task ring (rounded up to a power of 2)
  int64_t drain_ns = 20 * rt::kNsPerMs;  // how often the GDOS thread drains the rings
  bool lcm = true;                       // publish on LCM (needs the host's lcm: true)
  std::string lcm_url;                   // "": the host's TiMS URL
  std::string channel = "RACK_GDOS";
};

struct HostSettings {
  std::string file;
  std::string host;         // host name (default: the machine's)
  uint8_t system = 0;       // robot id: the system byte of every address here
  uint8_t host_id = 0;      // instance of this host's Executor(sys/id) mailbox
  bool require_rt = false;  // refuse to start without RT scheduling, locked memory, PREEMPT_RT
  std::string lcm_url;      // TiMS/LCM network ("" with lcm: false)
  bool lcm = true;
  // The `tims:` section (configs/two_robots/ shows every key). networks is empty
  // unless the file lists them; then lcm_url is not used.
  tims::NodeRole role = tims::NodeRole::kExecutor;
  std::vector<tims::NetworkConfig> networks;
  int64_t announce_period_ns = 1'000'000'000;
  int64_t expiry_ns = 3'000'000'000;
  uint32_t max_message_bytes = 4 * 1024 * 1024 + 4096;
  uint32_t large_slots = 4;
  int receive_priority = 0;  // TiMS/LCM receive threads: 0 normal, else SCHED_FIFO (below control tasks)
  std::size_t heap_prefault_bytes = 64u << 20;
  int cpu_dma_latency_us = 0;  // PM QoS bound held while running; -1: leave to the system
  // Events per task in the task-timeline rings (`trace_ring_events:`, a power of two):
  // 32 bytes each, preallocated and locked at start for every task.
  std::size_t trace_ring_events = 4096;
  // CPU partitioning (the `cpus:` block; configs/partitioned.yaml explains it). Both
  // empty: no partitioning. Otherwise both are set (a missing one is the online CPUs
  // less the other): RT tasks without a `cpu:` run on rt_cpus, every other thread of
  // rackd (non-RT tasks, GDOS, TiMS/LCM, library threads) on housekeeping_cpus.
  std::vector<int> rt_cpus;
  std::vector<int> housekeeping_cpus;
  std::vector<std::string> plugins;
  // Mode-switch detection (the `modeswitch:` block); rackd starts the detector.
  rt::modeswitch::Config modeswitch;
  GdosSettings gdos;
  // Keyed networks (`tims: replay_window_ms`): see rack/tims/link_auth.h.
  int64_t replay_window_ns = 5'000'000'000;
  // Access control (the `access:` section; configs/access_control.yaml explains it).
  // Without the section: no checks at all (open, and rackd warns at start).
  bool access_configured = false;
  tims::AccessConfig access;
  int64_t access_log_ns = 1'000'000'000;  // denials reach GDOS at most once per rule per this
};

// A validated host: the settings, and every component constructed with its
// parameters applied, in start order (dependencies first).
struct LoadedHost {
  HostSettings settings;
  std::vector<std::unique_ptr<Component>> components;
  std::vector<std::vector<std::size_t>> dependencies;  // per component: indices it depends on
};

struct LoadResult {
  std::unique_ptr<LoadedHost> host;  // null when errors is not empty
  std::vector<ConfigError> errors;
  // What loads but should change: a parameter given by its former name (file, line,
  // key and the new name; docs/parameters.md). rackd prints them and starts.
  std::vector<ConfigError> warnings;
};

struct HostLoadOptions {
  // Plug-ins are loaded (dlopen) and key files read while loading, so that --check
  // reports them. False: only their paths are checked, no file named by the input is
  // opened (the fuzz harness, tests/fuzz/fuzz_host_config.cpp).
  bool open_files = true;
  // rackd --check: every file and folder a parameter names (Parameter::Spec::path)
  // must exist. A normal start leaves that to the component (init() fails with the
  // path, the other components run).
  bool check_paths = false;
};

// The folder of a host file, absolute and normalised: relative paths in the file
// (plug-ins, key files, crash_dir, file parameters) are taken from it. Not RT-safe.
[[nodiscard]] std::string host_file_folder(const std::string& file);

// Reads and validates a host file. `caps` gives the online CPUs. The file must be a
// regular file of at most kMaxHostFileBytes (fstat before anything is read; opened
// non-blocking, so a FIFO never stalls the caller).
[[nodiscard]] LoadResult load_host_file(const std::string& path, ComponentRegistry& registry,
                                        const rt::RtCapabilities& caps, const HostLoadOptions& options = {});
// read_host_bytes and read_tool_network: rack/client/host_file.h.

// load_host_file from text (tests, tools); `file` names it in error messages.
// Decodes outside input: never throws for any text (every problem is an error).
[[nodiscard]] LoadResult load_host_text(const std::string& text, const std::string& file, ComponentRegistry& registry,
                                        const rt::RtCapabilities& caps, const HostLoadOptions& options = {});

}  // namespace rack
