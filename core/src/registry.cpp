#include "rack/core/registry.h"

#include "rack/core/plugin_abi.h"
#include "rack/rt/input_file.h"
#include "rack/tims/address.h"

#include <dirent.h>
#include <dlfcn.h>
#include <limits.h>
#include <link.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <set>
#include <stdexcept>

namespace rack {

namespace {
constexpr uint64_t kMaxPluginBytes = uint64_t{1} << 30;  // 1 GiB: a shared library, with debug info
constexpr uint64_t kMaxManifestBytes = 4096;
constexpr std::size_t kMaxManifestLine = 512;
constexpr const char* kManifestSuffix = ".rack-class";

#ifndef RACK_PLUGIN_BUILD_DIR
#define RACK_PLUGIN_BUILD_DIR ""
#endif
#ifndef RACK_PLUGIN_INSTALL_DIR
#define RACK_PLUGIN_INSTALL_DIR ""
#endif
#ifndef RACK_PLUGIN_INSTALL_RELDIR
#define RACK_PLUGIN_INSTALL_RELDIR ""
#endif
#ifndef RACK_BUILD_TREE_DIR
#define RACK_BUILD_TREE_DIR ""
#endif

bool is_directory(const std::string& path) {
  struct stat st {};
  return !path.empty() && ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

std::string dir_of(const std::string& path) {
  const auto slash = path.rfind('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

// The program this process runs (/proc/self/exe), "" when it cannot be read.
std::string own_program() {
  char buf[PATH_MAX];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof buf - 1);
  return n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string();
}

// Whether `path` (resolved) lies below directory `dir` (resolved here: the build tree
// may be reached through a symbolic link).
bool below(const std::string& path, const char* dir) {
  if (dir == nullptr || *dir == '\0') return false;
  char buf[PATH_MAX];
  const std::string d = ::realpath(dir, buf) != nullptr ? std::string(buf) : std::string(dir);
  return path.size() > d.size() && path.compare(0, d.size(), d) == 0 && path[d.size()] == '/';
}

bool printable_text(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return static_cast<unsigned char>(c) >= 0x20 && c != 0x7f; });
}

// A class name as host files write it: 1..63 letters, digits or '_'.
bool valid_class_name(const std::string& s) {
  if (s.empty() || s.size() > 63) return false;
  return std::all_of(s.begin(), s.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
  });
}
}  // namespace

bool read_plugin_manifest(const std::string& path, PluginClassInfo& out, std::string& error) {
  std::string text;
  if (!rt::read_regular_file(path, kMaxManifestBytes, "plug-in manifest", text, error)) return false;
  out = PluginClassInfo{};
  out.manifest = path;
  std::size_t line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    auto end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const std::string where = path + ":" + std::to_string(line_no) + ": ";
    if (line.size() > kMaxManifestLine) {
      error = where + "line longer than 512 bytes";
      return false;
    }
    if (!printable_text(line)) {
      error = where + "control character in the line";
      return false;
    }
    if (line.empty() || line[0] == '#') continue;
    const auto space = line.find(' ');
    const std::string key = line.substr(0, space);
    const std::string value = space == std::string::npos ? std::string() : line.substr(space + 1);
    if (key == "class") {
      if (!valid_class_name(value)) {
        error = where + "'class' needs a class name (letters, digits, '_')";
        return false;
      }
      out.impl = value;
    } else if (key == "library") {
      if (value.empty()) {
        error = where + "'library' needs a file name";
        return false;
      }
      out.library = value[0] == '/' ? value : dir_of(path) + "/" + value;
    } else if (key == "summary") {
      out.summary = value;
    } else if (key == "lock_dependencies") {
      if (value != "yes" && value != "no") {
        error = where + "'lock_dependencies' is yes or no";
        return false;
      }
      out.lock_dependencies = value == "yes";
    } else if (key == "interface") {
      if (!valid_class_name(value)) {
        error = where + "'interface' needs a TiMS class name";
        return false;
      }
      out.interface_name = value;
    } else {
      error = where + "unknown key '" + key + "' (class, interface, library, summary, lock_dependencies)";
      return false;
    }
  }
  if (out.impl.empty() || out.library.empty()) {
    error = path + ": a manifest needs a 'class' and a 'library' line";
    return false;
  }
  return true;
}

void ComponentRegistry::add(ComponentClass cls) {
  if (cls.impl.empty() || !cls.make) throw std::invalid_argument("component class without name or factory");
  const std::string name = cls.impl;
  if (classes_.count(name) != 0) throw std::invalid_argument("component class '" + name + "' registered twice");
  if (!cls.interface_name.empty() && !tims::register_class_name(cls.class_id, cls.interface_name)) {
    const char* taken = tims::class_name(cls.class_id);
    throw std::invalid_argument(
        "component class '" + name + "': TiMS class 0x" +
        [](uint8_t v) {
          constexpr char kHex[] = "0123456789abcdef";
          return std::string{kHex[v >> 4], kHex[v & 15]};
        }(cls.class_id) +
        " cannot be named '" + cls.interface_name + "'" +
        (taken != nullptr ? std::string(" (it is '") + taken + "')" : std::string(" (name taken)")));
  }
  classes_.emplace(name, std::move(cls));
}

const ComponentClass* ComponentRegistry::find(const std::string& impl) const {
  const auto it = classes_.find(impl);
  return it == classes_.end() ? nullptr : &it->second;
}

std::vector<const ComponentClass*> ComponentRegistry::all() const {
  std::vector<const ComponentClass*> out;
  for (const auto& [name, cls] : classes_) out.push_back(&cls);
  return out;
}

std::string ComponentRegistry::names() const {
  std::string s;
  for (const auto& [name, cls] : classes_) s += (s.empty() ? "" : ", ") + name;
  return s;
}

namespace {
// The real paths of the shared objects mapped now (as /proc/self/maps names them).
std::set<std::string> loaded_objects() {
  std::set<std::string> out;
  dl_iterate_phdr(
      [](dl_phdr_info* info, size_t, void* data) {
        if (info->dlpi_name != nullptr && info->dlpi_name[0] == '/') {
          char real[PATH_MAX];
          if (::realpath(info->dlpi_name, real) != nullptr) static_cast<std::set<std::string>*>(data)->insert(real);
        }
        return 0;
      },
      &out);
  return out;
}
}  // namespace

void ComponentRegistry::load_plugin(const std::string& path, bool lock_dependencies) {
  if (std::find(plugin_paths_.begin(), plugin_paths_.end(), path) != plugin_paths_.end()) return;
  // dlopen() would wait for ever on a FIFO and map whatever a device gives: a plug-in
  // is a regular file. Its ABI stamp is checked before dlopen() runs any of its code
  // (rack/core/plugin_abi.h), so it is named by a path (dlopen's own search would
  // load a file this check has not read).
  if (path.find('/') == std::string::npos) {
    throw std::runtime_error("cannot load plug-in '" + path + "': give its path (with a '/', e.g. ./" + path + ")");
  }
  std::string refused;
  if (!rt::check_regular_file(path, kMaxPluginBytes, "plug-in", refused)) {
    throw std::runtime_error("cannot load plug-in: " + refused);
  }
  if (!plugin_abi::check_plugin(path, kMaxPluginBytes, refused)) throw std::runtime_error(refused);
  const std::set<std::string> before = lock_dependencies ? std::set<std::string>{} : loaded_objects();
  void* handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) throw std::runtime_error(std::string("cannot load plug-in: ") + dlerror());
  using RegisterFn = void (*)(ComponentRegistry&);
  auto fn = reinterpret_cast<RegisterFn>(dlsym(handle, "rack_register_components"));
  if (fn == nullptr) {
    dlclose(handle);
    throw std::runtime_error("plug-in " + path + " has no 'rack_register_components' function");
  }
  fn(*this);
  plugins_.push_back(handle);
  plugin_paths_.push_back(path);
  if (lock_dependencies) any_locked_plugin_ = true;
  if (!lock_dependencies) {
    char plugin_real[PATH_MAX];
    const std::string self = ::realpath(path.c_str(), plugin_real) != nullptr ? plugin_real : path;
    for (const auto& lib : loaded_objects()) {
      if (before.count(lib) == 0 && lib != self) unlockable_.push_back(lib);
    }
  }
}

void ComponentRegistry::add_plugin_dir(const std::string& dir) {
  if (std::find(extra_dirs_.begin(), extra_dirs_.end(), dir) == extra_dirs_.end()) extra_dirs_.push_back(dir);
}

std::vector<std::string> ComponentRegistry::plugin_dirs() const {
  std::vector<std::string> dirs = extra_dirs_;
  auto add = [&dirs](const std::string& d) {
    if (!d.empty() && std::find(dirs.begin(), dirs.end(), d) == dirs.end()) dirs.push_back(d);
  };
  if (const char* env = std::getenv("RACK_PLUGIN_PATH"); env != nullptr) {
    const std::string path = env;
    std::size_t pos = 0;
    while (pos <= path.size()) {
      auto colon = path.find(':', pos);
      if (colon == std::string::npos) colon = path.size();
      add(path.substr(pos, colon - pos));
      pos = colon + 1;
    }
  }
  // The build tree's plug-ins only for a program of the build tree (rackd, the
  // tests): an installed rackd does not load what a later build leaves there.
  const std::string program = own_program();
  if (below(program, RACK_BUILD_TREE_DIR) && is_directory(RACK_PLUGIN_BUILD_DIR)) add(RACK_PLUGIN_BUILD_DIR);
  // The installed plug-ins beside an installed program (<prefix>/bin/rackd ->
  // <prefix>/lib/rack/plugins), so that an installed tree works wherever it is
  // copied, then those of the prefix it was configured for.
  if (!program.empty() && !below(program, RACK_BUILD_TREE_DIR) && std::string(RACK_PLUGIN_INSTALL_RELDIR) != "") {
    const std::string beside = dir_of(dir_of(program)) + "/" + RACK_PLUGIN_INSTALL_RELDIR;
    if (is_directory(beside)) add(beside);
  }
  add(RACK_PLUGIN_INSTALL_DIR);
  return dirs;
}

const ComponentClass* ComponentRegistry::resolve(const std::string& impl, std::string& error) {
  if (const ComponentClass* cls = find(impl)) return cls;
  const auto dirs = plugin_dirs();
  std::string searched;
  for (const auto& d : dirs) searched += (searched.empty() ? "" : ", ") + d;
  if (!valid_class_name(impl)) {
    error = "unknown component class '" + impl + "' (known: " + names() + ")";
    return nullptr;
  }
  for (const auto& dir : dirs) {
    const std::string manifest = dir + "/" + impl + kManifestSuffix;
    struct stat st {};
    if (::stat(manifest.c_str(), &st) != 0) continue;
    PluginClassInfo info;
    std::string why;
    if (!read_plugin_manifest(manifest, info, why)) {
      error = "class '" + impl + "': broken plug-in manifest: " + why;
      return nullptr;
    }
    if (info.impl != impl) {
      error = "class '" + impl + "': plug-in manifest " + manifest + " declares class '" + info.impl + "'";
      return nullptr;
    }
    try {
      load_plugin(info.library, info.lock_dependencies);
    } catch (const std::exception& e) {
      error = "class '" + impl + "': plug-in " + info.library + " (manifest " + manifest + "): " + e.what();
      return nullptr;
    }
    if (const ComponentClass* cls = find(impl)) return cls;
    error = "class '" + impl + "': plug-in " + info.library + " loaded but did not register the class";
    return nullptr;
  }
  error = "unknown component class '" + impl + "': not built in (" + names() + ") and no plug-in " + impl +
          kManifestSuffix + " in " + (searched.empty() ? std::string("(no plug-in directory)") : searched);
  return nullptr;
}

std::vector<PluginClassInfo> ComponentRegistry::plugin_classes(std::vector<std::string>* problems) const {
  std::vector<PluginClassInfo> out;
  std::set<std::string> seen;
  for (const auto& dir : plugin_dirs()) {
    DIR* d = ::opendir(dir.c_str());
    if (d == nullptr) continue;
    std::vector<std::string> files;
    while (const dirent* e = ::readdir(d)) {
      const std::string name = e->d_name;
      if (name.size() > std::char_traits<char>::length(kManifestSuffix) && name.ends_with(kManifestSuffix)) {
        files.push_back(name);
      }
    }
    ::closedir(d);
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      PluginClassInfo info;
      std::string why;
      if (!read_plugin_manifest(dir + "/" + f, info, why)) {
        if (problems != nullptr) problems->push_back(why);
        continue;
      }
      if (seen.insert(info.impl).second) out.push_back(std::move(info));
    }
  }
  return out;
}

namespace {
TypeDescription describe_type(const DataTypeInfo& t) {
  TypeDescription out;
  out.name = t.type_name != nullptr ? t.type_name : "";
  out.size = t.size;
  for (const tims::FieldDesc& f : t.fields) out.fields.push_back({f.name, f.kind, f.offset, f.count, {}});
  return out;
}
}  // namespace

ClassDescription describe_class(const ComponentClass& cls, const ParameterSet& params) {
  ClassDescription d;
  d.impl = cls.impl;
  const char* tims_name = tims::class_name(cls.class_id);
  d.class_name = tims_name != nullptr ? tims_name : cls.impl;
  d.class_id = cls.class_id;
  d.summary = cls.description;
  if (cls.data != nullptr) {
    d.data = describe_type(*cls.data);
    for (const FieldUnit& u : cls.data->units) {
      const std::string field = u.field != nullptr ? u.field : "";
      FieldDescription* f = nullptr;
      for (auto& c : d.data->fields) {
        if (c.name == field) f = &c;
      }
      if (f == nullptr || !f->unit.empty()) {
        throw std::invalid_argument("class '" + cls.impl + "': unit of field '" + field + "': '" + d.data->name +
                                    (f == nullptr ? "' has no such field" : "' gives it a unit twice"));
      }
      f->unit = u.unit != nullptr ? u.unit : "";
      if (f->unit.empty()) throw std::invalid_argument("class '" + cls.impl + "': field '" + field + "': empty unit");
    }
    for (const FieldValueNames& n : cls.data->value_names) {
      FieldNamesDescription fd;
      fd.field = n.field != nullptr ? n.field : "";
      fd.address = n.address;
      for (const ValueName& v : n.values) fd.values.push_back({v.value, v.name != nullptr ? v.name : ""});
      d.value_names.push_back(std::move(fd));
    }
  }
  for (const CommandInfo& c : cls.commands) {
    CommandDescription cd;
    cd.name = c.name != nullptr ? c.name : "";
    cd.type = c.type;
    cd.summary = c.summary != nullptr ? c.summary : "";
    if (c.body != nullptr) cd.body = describe_type(*c.body);
    d.commands.push_back(std::move(cd));
  }
  for (std::size_t i = 0; i < params.size(); ++i) {
    const Parameter& p = params.at(i);
    const Parameter::Spec& s = p.spec();
    ParameterDescription pd;
    pd.name = p.name();
    pd.kind = p.kind();
    pd.flags = static_cast<uint8_t>((s.required ? ParameterDescription::kRequired : 0) |
                                    (s.init_only ? ParameterDescription::kInitOnly : 0) |
                                    (s.component_ref ? ParameterDescription::kComponentRef : 0));
    pd.unit = s.unit;
    pd.min = s.min;
    pd.max = s.max;
    pd.default_value = p.value_text();
    pd.doc = s.doc;
    pd.choices = s.choices;
    d.parameters.push_back(std::move(pd));
  }
  return d;
}

}  // namespace rack
