#include "rack/core/registry.h"

#include "rack/rt/input_file.h"
#include "rack/tims/address.h"

#include <dlfcn.h>

#include <stdexcept>

namespace rack {

namespace {
constexpr uint64_t kMaxPluginBytes = uint64_t{1} << 30;  // 1 GiB: a shared library, with debug info
}  // namespace

void ComponentRegistry::add(ComponentClass cls) {
  if (cls.impl.empty() || !cls.make) throw std::invalid_argument("component class without name or factory");
  const std::string name = cls.impl;
  if (!classes_.emplace(name, std::move(cls)).second) {
    throw std::invalid_argument("component class '" + name + "' registered twice");
  }
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

void ComponentRegistry::load_plugin(const std::string& path) {
  // dlopen() would wait for ever on a FIFO and map whatever a device gives: a plug-in
  // is a regular file (a path without '/' is dlopen's to search, as before).
  if (path.find('/') != std::string::npos) {
    std::string refused;
    if (!rt::check_regular_file(path, kMaxPluginBytes, "plug-in", refused)) {
      throw std::runtime_error("cannot load plug-in: " + refused);
    }
  }
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
}

namespace {
TypeDescription describe_type(const DataTypeInfo& t) {
  TypeDescription out;
  out.name = t.type_name != nullptr ? t.type_name : "";
  out.size = t.size;
  for (const tims::FieldDesc& f : t.fields) out.fields.push_back({f.name, f.kind, f.offset, f.count});
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
  if (cls.data != nullptr) d.data = describe_type(*cls.data);
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
