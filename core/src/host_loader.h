// The host file loader (internal to core): one class per part of a host file, each with
// the state it needs, sharing the load's report (rack/core/host_config.h describes the
// format and its limits).
//
//   HostReport        the messages of one load (file, errors, warnings)
//   HostValueReader   a key's value checked and converted, errors with their position;
//                     every reader below is one        host_config_values.cpp
//   HostTextCheck     bytes (UTF-8, control characters) and YAML events (duplicate
//                     keys, nesting, one document) before the tree is built
//                                                      host_config_text.cpp
//   TaskReader        command_task/data_task settings, the modeswitch: block
//                                                      host_config_tasks.cpp
//   CpuPartition      cpus: (rt and housekeeping sets), tims.receive_priority below
//                     every task                       host_config_cpus.cpp
//   NetworkReader     tims: (role, timing, networks, key files), gdos:
//                                                      host_config_network.cpp
//   AccessReader      access: (rules, the names and patterns they protect)
//                                                      host_config_access.cpp
//   HostPaths         plugins: (loaded), relative paths, --check of parameter paths
//                                                      host_config_paths.cpp
//   HostLoader        the walk of the top-level map (host_config.cpp) and the
//                     components: list (class, tasks, params, references, order;
//                     host_config_components.cpp)
//
// Real-time contract: set-up only, nothing here is RT-safe. Thread-safety: one
// HostLoader (and its readers) per load, used by one thread.
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

// The messages of one load, each with the file, line and column it is about.
struct HostReport {
  std::string file;
  std::vector<ConfigError> errors;
  std::vector<ConfigError> warnings;
};

class HostValueReader {
 public:
  explicit HostValueReader(HostReport& report) : report_(report) {}

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

 protected:
  HostReport& report_;
};

class HostTextCheck : public HostValueReader {
 public:
  using HostValueReader::HostValueReader;
  // False: not parsed at all (the first problem is reported).
  bool check_text(std::string_view text);
  // False: the first document is not YAML.
  bool check_events(const std::string& text);
};

class TaskReader : public HostValueReader {
 public:
  // `base_dir`: the host file's folder (crash_dir is relative to it).
  TaskReader(HostReport& report, const rt::RtCapabilities& caps, const std::string& base_dir)
      : HostValueReader(report), caps_(caps), base_dir_(base_dir) {}
  void read_task(const YAML::Node& node, TaskSettings& task, const std::string& where,
                 const std::set<std::string>& extra_keys, int64_t min_priority = 1);
  void read_modeswitch(const YAML::Node& node, rt::modeswitch::Config& c);

 private:
  std::optional<rt::modeswitch::Mode> get_mode(const YAML::Node& map, const char* key);

  const rt::RtCapabilities& caps_;
  const std::string& base_dir_;
};

class CpuPartition : public HostValueReader {
 public:
  CpuPartition(HostReport& report, const rt::RtCapabilities& caps) : HostValueReader(report), caps_(caps) {}
  void read_cpus(const YAML::Node& node, HostSettings& hs);
  void check_receive_priority(const YAML::Node& root, const LoadedHost& host);

 private:
  bool read_cpu_set(const YAML::Node& node, const std::string& key, std::vector<int>& out);

  const rt::RtCapabilities& caps_;
};

class NetworkReader : public HostValueReader {
 public:
  NetworkReader(HostReport& report, const std::string& base_dir, const HostLoadOptions& options)
      : HostValueReader(report), base_dir_(base_dir), options_(options) {}
  void read_gdos(const YAML::Node& g, GdosSettings& out);
  void load_tims(const YAML::Node& t, HostSettings& hs, bool have_lcm_url);

 private:
  const std::string& base_dir_;
  const HostLoadOptions& options_;
};

class AccessReader : public HostValueReader {
 public:
  // `component_addresses`: every component's address by name (rules name components).
  AccessReader(HostReport& report, const std::map<std::string, tims::Address>& component_addresses)
      : HostValueReader(report), component_addresses_(component_addresses) {}
  void read_access(const YAML::Node& a, LoadedHost& host);

 private:
  bool read_access_addresses(const YAML::Node& node, const char* key, std::vector<tims::AddressMask>& out,
                             tims::AccessRuleConfig* rule);

  const std::map<std::string, tims::Address>& component_addresses_;
};

class HostPaths : public HostValueReader {
 public:
  HostPaths(HostReport& report, ComponentRegistry& registry, const std::string& base_dir,
            const HostLoadOptions& options)
      : HostValueReader(report), registry_(registry), base_dir_(base_dir), options_(options) {}
  // Plug-in directories are given to the registry, files loaded (when files may be opened).
  void read_plugins(const YAML::Node& plugins, HostSettings& hs);
  // --check: the files and folders a component's parameters name exist.
  void check_parameter_paths(const YAML::Node& node, const std::string& name, const ParameterSet& params,
                             const std::map<const Parameter*, YAML::Mark>& marks);

 private:
  std::string relative_note(const std::string& given) const;

  ComponentRegistry& registry_;
  const std::string& base_dir_;
  const HostLoadOptions& options_;
};

// Friend of Component: sets settings and resolved references.
struct HostLoader : public HostValueReader {
 public:
  HostLoader(HostReport& report, ComponentRegistry& registry, const rt::RtCapabilities& caps,
             const HostLoadOptions& options);

  static std::string tims_default_url() { return "udpm://239.255.76.67:7667?ttl=0"; }

  // host_config.cpp: the walk of the file's top-level map
  LoadResult load(const std::string& text);

 private:
  // host_config_components.cpp: the components: list, their parameters and dependencies
  void load_components(const YAML::Node& comps, LoadedHost& host);

  ComponentRegistry& registry_;
  HostLoadOptions options_;
  // The host file's folder, absolute: every relative path the file holds (plug-ins,
  // key files, crash_dir, parameters with a Parameter::Spec::path) is taken from here.
  std::string base_dir_;
  // Every component's address by name (filled while loading them, even when another
  // component has errors, so that the access rules resolve names regardless).
  std::map<std::string, tims::Address> component_addresses_;
  HostTextCheck text_;
  TaskReader tasks_;
  CpuPartition cpus_;
  NetworkReader network_;
  AccessReader access_;
  HostPaths paths_;
};

}  // namespace rack
