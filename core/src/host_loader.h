// The host file loader (internal to core): HostLoader's state and which file holds which
// part of a host file. rack/core/host_config.h describes the format and its limits.
//
//   host_config.cpp             the top-level map, load_host_text/load_host_file
//   host_config_text.cpp        bytes (UTF-8, control characters) and YAML events (duplicate
//                               keys, nesting, one document) before the tree is built
//   host_config_values.cpp      typed values with ranges, key lists, names, URLs; the error
//                               list with file, line and column
//   host_config_tasks.cpp       command_task/data_task settings, the modeswitch: block
//   host_config_cpus.cpp        cpus: (rt and housekeeping sets), tims.receive_priority
//   host_config_network.cpp     tims: (role, timing, networks), gdos:, access:
//   host_config_paths.cpp       plugins:, relative paths, --check of parameter paths
//   host_config_components.cpp  components: (class, tasks, params, references, order)
//
// Real-time contract: set-up only, nothing here is RT-safe. Thread-safety: one
// HostLoader per load, used by one thread.
#pragma once

#include <yaml-cpp/yaml.h>

#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "rack/core/host_config.h"

namespace rack {

// Host file messages quote the file's keys and values: clean text of bounded length for
// a terminal and a log, whatever the file held (host_config_text.cpp).
std::string clean_host_message(const std::string& message);

// Friend of Component: sets settings and resolved references.
struct HostLoader {
  std::string file;
  ComponentRegistry& registry;
  const rt::RtCapabilities& caps;
  HostLoadOptions options;
  std::vector<ConfigError> errors;
  std::vector<ConfigError> warnings;
  // The host file's folder, absolute: every relative path the file holds (plug-ins,
  // key files, crash_dir, parameters with a Parameter::Spec::path) is taken from here.
  std::string base_dir;
  // Every component's address by name (filled while loading them, even when another
  // component has errors, so that the access rules resolve names regardless).
  std::map<std::string, tims::Address> component_addresses;

  template <typename T>
  bool get(const YAML::Node& map, const char* key, T& out, const std::string& what) {
    const YAML::Node n = map[key];
    if (!n) return false;
    if (!n.IsScalar()) {
      error(n.Mark(), std::string("'") + key + "' must be " + what);
      return false;
    }
    try {
      out = n.as<T>();
      return true;
    } catch (const YAML::Exception&) {
      error(n.Mark(), std::string("'") + key + "' must be " + what + ", got '" + n.Scalar() + "'");
      return false;
    }
  }

  static std::string tims_default_url() { return "udpm://239.255.76.67:7667?ttl=0"; }

  // host_config.cpp: the walk of the file's top-level map, and the public entry points
  LoadResult load(const std::string& text);

  // host_config_text.cpp: the bytes and the YAML events before any node is built
  bool check_text(std::string_view text);
  bool check_events(const std::string& text);

  // host_config_values.cpp: a key's value checked and converted, errors with their position
  void error(const YAML::Mark& mark, const std::string& message);
  void warn(const YAML::Mark& mark, const std::string& message);
  void check_keys(const YAML::Node& map, const std::set<std::string>& known, const std::string& where);
  bool get_int_range(const YAML::Node& map, const char* key, int64_t lo, int64_t hi, int64_t& out,
                     const std::string& what);
  bool get_positive_ms(const YAML::Node& map, const char* key, int64_t& out_ns);
  // A duration in milliseconds (a float, as every *_ms: docs/parameters.md) in
  // lo_ms..hi_ms, to nanoseconds.
  bool get_ms_range(const YAML::Node& map, const char* key, double lo_ms, double hi_ms, int64_t& out_ns,
                    const std::string& what);
  static bool valid_name(const std::string& n, std::size_t max = kMaxNameLength, bool dots = false);
  static std::string printable(const std::string& n);
  void check_url(const YAML::Node& map, const char* key, const std::string& url);

  // host_config_tasks.cpp: a task's priority, CPU and stack; the modeswitch: block
  void read_task(const YAML::Node& node, TaskSettings& task, const std::string& where,
                 const std::set<std::string>& extra_keys, int64_t min_priority = 1);
  std::optional<rt::modeswitch::Mode> get_mode(const YAML::Node& map, const char* key);
  void read_modeswitch(const YAML::Node& node, rt::modeswitch::Config& c);

  // host_config_cpus.cpp: CPU sets and partitioning (cpus:), the receive priority below every task
  bool read_cpu_set(const YAML::Node& node, const std::string& key, std::vector<int>& out);
  void read_cpus(const YAML::Node& node, HostSettings& hs);
  void check_receive_priority(const YAML::Node& root, const LoadedHost& host);

  // host_config_network.cpp: the tims:, gdos: and access: sections
  void read_gdos(const YAML::Node& g, GdosSettings& out);
  void load_tims(const YAML::Node& t, HostSettings& hs, bool have_lcm_url);
  bool read_access_addresses(const YAML::Node& node, const char* key, std::vector<tims::AddressMask>& out,
                             tims::AccessRuleConfig* rule);
  void read_access(const YAML::Node& a, LoadedHost& host);

  // host_config_paths.cpp: plug-ins and the paths a file names (relative to its folder)
  std::string relative_note(const std::string& given) const;
  void check_parameter_paths(const YAML::Node& node, const std::string& name, const ParameterSet& params,
                             const std::map<const Parameter*, YAML::Mark>& marks);
  void read_plugins(const YAML::Node& plugins, HostSettings& hs);

  // host_config_components.cpp: the components: list, their parameters and dependencies
  void load_components(const YAML::Node& comps, LoadedHost& host);
};

}  // namespace rack
