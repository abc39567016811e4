// Component classes by implementation name. The executor knows classes only by
// name (DESIGN.md); each component library registers its classes, and plug-ins
// named in a host file register theirs from `rack_register_components`.
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
  // Throws std::runtime_error with dlerror()'s text.
  void load_plugin(const std::string& path);

 private:
  std::map<std::string, ComponentClass> classes_;
  std::vector<void*> plugins_;  // kept open for the process lifetime
};

// The description of `cls` that its components serve (GET_CLASS), with the
// parameters `params` declares (a freshly made component's: the defaults are the
// declared values). The class name of its addresses is TiMS' name for its class id,
// else its impl name. Throws std::invalid_argument when the class breaks a limit of
// the description (rack/core/class_description.h). Not RT-safe.
[[nodiscard]] ClassDescription describe_class(const ComponentClass& cls, const ParameterSet& params);

}  // namespace rack
