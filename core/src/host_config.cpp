#include "rack/core/host_config.h"

#include <unistd.h>

#include <filesystem>

#include "host_loader.h"

namespace rack {

HostLoader::HostLoader(HostReport& report, ComponentRegistry& registry, const rt::RtCapabilities& caps,
                       const HostLoadOptions& options)
    : HostValueReader(report),
      registry_(registry),
      options_(options),
      base_dir_(host_file_folder(report.file)),
      text_(report),
      tasks_(report, caps, base_dir_),
      cpus_(report, caps),
      network_(report, base_dir_, options_),
      access_(report, component_addresses_),
      paths_(report, registry, base_dir_, options_) {}

LoadResult HostLoader::load(const std::string& text) {
  LoadResult result;
  YAML::Node root;
  if (!text_.check_text(text) || !text_.check_events(text)) {
    result.errors = report_.errors;
    return result;
  }
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    error(e.mark, "YAML syntax: " + e.msg);
    result.errors = report_.errors;
    return result;
  }
  if (!root || root.IsNull()) {
    report_.errors.push_back({report_.file, 0, 0, "empty host file (expected a map with 'components')"});
    result.errors = report_.errors;
    return result;
  }
  if (!root.IsMap()) {
    error(root.Mark(), "a host file is a map (host, system, components, ...)");
    result.errors = report_.errors;
    return result;
  }
  auto host = std::make_unique<LoadedHost>();
  HostSettings& hs = host->settings;
  hs.file = report_.file;
  check_keys(root,
             {"host", "system", "host_id", "require_rt", "lcm", "lcm_url", "heap_prefault_mib", "cpu_dma_latency_us",
              "trace_ring_events", "cpus", "plugins", "modeswitch", "components", "gdos", "tims", "access"},
             "the host file");
  char hostname[256] = {};
  gethostname(hostname, sizeof hostname - 1);
  hs.host = hostname;
  if (get(root, "host", hs.host, "a host name") && !valid_name(hs.host, kMaxHostNameLength, true)) {
    error(root["host"].Mark(), "host name '" + printable(hs.host) + "' must be 1.." +
                                   std::to_string(kMaxHostNameLength) + " letters, digits, '.', '_' or '-'");
  }
  int64_t v = 0;
  if (get_int_range(root, "system", 0, 254, v, "a system (robot) id 0..254")) hs.system = static_cast<uint8_t>(v);
  if (get_int_range(root, "host_id", 0, 255, v, "a host id 0..255")) hs.host_id = static_cast<uint8_t>(v);
  get(root, "require_rt", hs.require_rt, "true or false");
  get(root, "lcm", hs.lcm, "true or false");
  hs.lcm_url = tims_default_url();
  if (get(root, "lcm_url", hs.lcm_url, "an LCM URL such as udpm://239.255.76.67:7667?ttl=0")) {
    check_url(root, "lcm_url", hs.lcm_url);
  }
  if (get_int_range(root, "heap_prefault_mib", 0, 16384, v, "a size in MiB")) {
    hs.heap_prefault_bytes = static_cast<std::size_t>(v) << 20;
  }
  if (get_int_range(root, "cpu_dma_latency_us", -1, 100000, v,
                    "a latency bound in us (0: shallowest idle state; -1: leave to the system)")) {
    hs.cpu_dma_latency_us = static_cast<int>(v);
  }
  if (get_int_range(root, "trace_ring_events", 16, 1 << 20, v, "a number of events (a power of two)")) {
    if ((v & (v - 1)) != 0) {
      error(root["trace_ring_events"].Mark(),
            "'trace_ring_events' = " + std::to_string(v) + " is not a power of two (e.g. 1024, 4096, 16384)");
    } else {
      hs.trace_ring_events = static_cast<std::size_t>(v);
    }
  }
  if (const YAML::Node cpus = root["cpus"]) cpus_.read_cpus(cpus, hs);
  if (const YAML::Node ms = root["modeswitch"]) tasks_.read_modeswitch(ms, hs.modeswitch);
  if (const YAML::Node t = root["tims"]) network_.load_tims(t, hs, root["lcm_url"].IsDefined());
  if (const YAML::Node plugins = root["plugins"]) paths_.read_plugins(plugins, hs);
  if (const YAML::Node g = root["gdos"]) network_.read_gdos(g, hs.gdos);
  const YAML::Node comps = root["components"];
  if (!comps) {
    report_.errors.push_back({report_.file, 0, 0, "missing 'components' (the list of components to run)"});
  } else if (!comps.IsSequence()) {
    error(comps.Mark(), "'components' must be a list");
  } else {
    load_components(comps, *host);
  }
  if (const YAML::Node a = root["access"]) access_.read_access(a, *host);
  cpus_.check_receive_priority(root, *host);
  if (!report_.errors.empty()) {
    result.errors = report_.errors;
    return result;
  }
  result.host = std::move(host);
  result.warnings = report_.warnings;
  return result;
}

std::string host_file_folder(const std::string& file) {
  // Not canonical (symbolic links stay as the user named them); "" on an error of the
  // working directory: relative paths are then the process's.
  std::error_code ec;
  std::filesystem::path dir = std::filesystem::path(file).parent_path();
  if (dir.empty()) dir = ".";
  dir = std::filesystem::absolute(dir, ec);
  if (ec) return {};
  std::string out = dir.lexically_normal().string();
  while (out.size() > 1 && out.back() == '/') out.pop_back();
  return out;
}

LoadResult load_host_text(const std::string& text, const std::string& file, ComponentRegistry& registry,
                          const rt::RtCapabilities& caps, const HostLoadOptions& options) {
  HostReport report{file, {}, {}};
  HostLoader loader(report, registry, caps, options);
  // Outside input: whatever escapes the checks (a yaml-cpp conversion that throws, an
  // allocation that fails) is one more error of this file, never an exception.
  LoadResult r;
  try {
    r = loader.load(text);
  } catch (const std::exception& e) {
    r.host.reset();
    r.errors = report.errors;
    r.errors.push_back({file, 0, 0, std::string("cannot load the host file: ") + e.what()});
  }
  // Messages quote the file's keys and values: they go to a terminal and a log as
  // clean text of bounded length, whatever the file held.
  for (auto& e : r.errors) e.message = clean_host_message(e.message);
  for (auto& w : r.warnings) w.message = clean_host_message(w.message);
  return r;
}

LoadResult load_host_file(const std::string& path, ComponentRegistry& registry, const rt::RtCapabilities& caps,
                          const HostLoadOptions& options) {
  std::string why;
  const auto text = read_host_bytes(path, why);
  if (!text) {
    LoadResult r;
    r.errors.push_back({path, 0, 0, why});
    return r;
  }
  return load_host_text(*text, path, registry, caps, options);
}

}  // namespace rack
