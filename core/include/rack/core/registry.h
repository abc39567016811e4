// Component classes by implementation name. The executor knows classes only by
// name (DESIGN.md). Each class is declared once in its folder (components/<class>/
// CMakeLists.txt, rack_add_class(): cmake/RackClass.cmake); the built-in ones are
// registered by generated code (rack::components::register_builtin), the heavy ones
// are plug-ins: a MODULE library with a manifest `<Class>.rack-class` in a plug-in
// directory, loaded only when a host file names the class (resolve()).
//
// Plug-in directories, searched in this order: the host file's `plugins:` entries
// that are directories, RACK_PLUGIN_PATH (':'-separated), the build tree's plug-in
// directory (baked in when built in the tree; searched only when /proc/self/exe lies
// below the build tree), the installed one beside an installed program
// (<exe>/../${CMAKE_INSTALL_LIBDIR}/rack/plugins) and the configured prefix's.
//
// Real-time contract: not RT-safe (set-up only). Not thread-safe.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "rack/core/class_description.h"
#include "rack/core/class_types.h"
#include "rack/core/component.h"

namespace rack {

struct ComponentClass {
  std::string impl;         // the name host files use: "Generator"
  uint8_t class_id = 0;     // TiMS class of its addresses (rack::tims::classes)
  std::string description;  // one line for --list-classes
  std::function<std::unique_ptr<Component>()> make;
  // What the class declares about its messages (served to tools by the executor):
  // the sample type it publishes (nullptr: none) and its class commands.
  const DataTypeInfo* data = nullptr;
  std::span<const CommandInfo> commands{};
  // The TiMS class name its addresses print with ("Chassis" for ChassisSim);
  // registered with tims::register_class_name() by add(). Empty: none.
  std::string interface_name{};
};

// A plug-in class as its manifest names it (not loaded).
struct PluginClassInfo {
  std::string impl;            // "MCL"
  std::string manifest;        // the manifest file
  std::string library;         // the MODULE library it names (absolute)
  std::string summary;         // one line
  std::string interface_name;  // its TiMS class name ("Chassis"), if the manifest says
  // false (`lock_dependencies no`): the libraries the plug-in brings (MRPT for MCL)
  // run only in non-RT work, so rackd leaves them out of its locked memory.
  bool lock_dependencies = true;
};

class ComponentRegistry {
 public:
  // Throws std::invalid_argument when the name is taken.
  void add(ComponentClass cls);
  [[nodiscard]] const ComponentClass* find(const std::string& impl) const;
  [[nodiscard]] std::vector<const ComponentClass*> all() const;
  [[nodiscard]] std::string names() const;  // "A, B, C"

  // Loads a plug-in (dlopen) and calls its
  //   extern "C" void rack_register_components(rack::ComponentRegistry&);
  // `path` names the file (with a '/'). Before dlopen() its ABI stamp is checked
  // (rack/core/plugin_abi.h: refused when it is not this rackd's). Throws
  // std::runtime_error with the reason (the file, the ABI it was built for and the one
  // expected, or dlerror()'s text). A library loaded before is not loaded again.
  void load_plugin(const std::string& path) { load_plugin(path, true); }

  // The class `impl`: registered, or else loaded from the plug-in whose manifest
  // `<impl>.rack-class` is found first in plugin_dirs(). nullptr with `error` set
  // (the class name, the directories searched, or why the plug-in did not load).
  const ComponentClass* resolve(const std::string& impl, std::string& error);

  // Searched before RACK_PLUGIN_PATH and the built-in directories.
  void add_plugin_dir(const std::string& dir);
  [[nodiscard]] std::vector<std::string> plugin_dirs() const;
  // Every plug-in class whose manifest is in plugin_dirs() (first one wins), by name,
  // without loading any library. Malformed manifests are left out with a line in
  // `problems` (file: what).
  [[nodiscard]] std::vector<PluginClassInfo> plugin_classes(std::vector<std::string>* problems = nullptr) const;

  // The shared objects (real paths) that plug-ins loaded with lock_dependencies =
  // false brought in and rackd did not map before: rt::unlock_file_mappings().
  // Empty as soon as any other plug-in is loaded (it may share them; kept locked).
  [[nodiscard]] std::vector<std::string> unlockable_libraries() const {
    return any_locked_plugin_ ? std::vector<std::string>{} : unlockable_;
  }

 private:
  void load_plugin(const std::string& path, bool lock_dependencies);

  std::map<std::string, ComponentClass> classes_;
  std::vector<void*> plugins_;             // kept open for the process lifetime
  std::vector<std::string> plugin_paths_;  // the libraries loaded (as given)
  std::vector<std::string> extra_dirs_;
  std::vector<std::string> unlockable_;
  bool any_locked_plugin_ = false;
};

// The description of `cls` that its components serve (GET_CLASS), with the
// parameters `params` declares (a freshly made component's: the defaults are the
// declared values). The class name of its addresses is TiMS' name for its class id,
// else its impl name. Throws std::invalid_argument when the class breaks a limit of
// the description (rack/core/class_description.h). Not RT-safe.
[[nodiscard]] ClassDescription describe_class(const ComponentClass& cls, const ParameterSet& params);
// Reads a plug-in manifest (`class NAME`, `library FILE`, `summary TEXT`,
// `interface NAME` lines; # comments). The library is made absolute against the manifest's directory. false
// with `error` (file:line: what) when malformed. Not RT-safe.
bool read_plugin_manifest(const std::string& path, PluginClassInfo& out, std::string& error);

}  // namespace rack
