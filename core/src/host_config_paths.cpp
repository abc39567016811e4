// Host files: plug-ins and the paths a file names, taken from the host file's folder;
// --check looks at the files and folders that components' parameters name.
#include "host_loader.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstring>

namespace rack {

// What an error about a path adds when the file gave it relative.
std::string HostPaths::relative_note(const std::string& given) const {
  if (given.empty() || given.front() == '/') return {};
  return " ('" + given + "' is relative to the host file's folder, " + base_dir_ + ")";
}

// --check: the files and folders a component's parameters name exist (what init()
// or the first STORE_DATA would otherwise find out after the start).
void HostPaths::check_parameter_paths(const YAML::Node& node, const std::string& name, const ParameterSet& params,
                                      const std::map<const Parameter*, YAML::Mark>& marks) {
  for (std::size_t i = 0; i < params.size(); ++i) {
    const Parameter& prm = params.at(i);
    const PathRole role = prm.spec().path;
    if (role == PathRole::kNone || role == PathRole::kDevice) continue;
    const std::string value = prm.get_string();
    if (value.empty()) continue;
    const auto at = marks.find(&prm);
    const YAML::Mark mark = at != marks.end() ? at->second : node.Mark();
    const std::string given = at != marks.end() ? node["params"][prm.name()].Scalar() : value;
    std::string target = value;
    if (role == PathRole::kOutput) {
      const auto slash = value.find_last_of('/');
      target = slash == std::string::npos ? "." : slash == 0 ? "/" : value.substr(0, slash);
    }
    const char* what = role == PathRole::kInput ? "" : role == PathRole::kOutput ? "the folder of " : "";
    struct stat st {};
    std::string problem;
    if (::stat(target.c_str(), &st) != 0) {
      const int e = errno;
      problem = std::string(what) + target + ": " + std::strerror(e);
      // A log shipped compressed (bench/data/carmen): say how to get the file read.
      struct stat gz {};
      if (e == ENOENT && role == PathRole::kInput && ::stat((target + ".gz").c_str(), &gz) == 0) {
        problem += " (" + target + ".gz is beside it: unpack it with gunzip -k " + target + ".gz)";
      }
    } else if (role != PathRole::kInput && !S_ISDIR(st.st_mode)) {
      problem = target + ": not a folder";
    }
    if (!problem.empty()) {
      error(mark, "component '" + name + "': parameter '" + prm.name() + "': " + problem + relative_note(given));
    }
  }
}

// The `plugins:` list: a directory is searched for plug-in classes by name, a file is
// loaded now (only when files may be opened).
void HostPaths::read_plugins(const YAML::Node& plugins, HostSettings& hs) {
  if (!plugins.IsSequence()) {
    error(plugins.Mark(), "'plugins' must be a list of plug-in directories or shared library paths");
  } else {
    for (const auto& p : plugins) {
      if (!p.IsScalar()) {
        error(p.Mark(), "a plug-in is a path");
        continue;
      }
      if (p.Scalar().empty()) {
        error(p.Mark(), "a plug-in path must not be empty");
        continue;
      }
      if (!options_.open_files) continue;
      const std::string path = resolve_path(base_dir_, p.Scalar());
      // A directory is searched for plug-in classes by name (<Class>.rack-class,
      // loaded only when a component names the class); a file is loaded now.
      struct stat st {};
      if (::stat(path.c_str(), &st) != 0) {
        const int e = errno;
        error(p.Mark(), "plug-in " + path + ": " + std::strerror(e) + relative_note(p.Scalar()));
        continue;
      }
      if (S_ISDIR(st.st_mode)) {
        registry_.add_plugin_dir(path);
        hs.plugins.push_back(path);
        continue;
      }
      try {
        registry_.load_plugin(path);
        hs.plugins.push_back(path);
      } catch (const std::exception& e) {
        error(p.Mark(), e.what());
      }
    }
  }
}

}  // namespace rack
