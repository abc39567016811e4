// Host files: the components: list: each component's class, address, tasks and
// parameters, then the references between them resolved into a start order.
#include "host_loader.h"

#include "rack/core/data_component.h"

#include <cmath>
#include <functional>
#include <optional>
#include <utility>

namespace rack {

void HostLoader::load_components(const YAML::Node& comps, LoadedHost& host) {
  struct Pending {
    YAML::Node node;
    std::unique_ptr<Component> component;
    std::vector<std::pair<Parameter*, YAML::Node>> refs;
  };
  std::vector<Pending> pending;
  std::map<std::string, std::size_t> by_name;
  std::map<uint32_t, std::size_t> by_address;
  for (const auto& node : comps) {
    if (!node.IsMap()) {
      error(node.Mark(), "a component is a map (name, class, instance, tasks, params)");
      continue;
    }
    check_keys(node,
               {"name", "class", "instance", "autostart", "retry_ms", "rpc_timeout_ms", "rpc_retries", "command_task",
                "data_task", "params"},
               "a component");
    std::string name, impl;
    if (!node["name"]) {
      error(node.Mark(), "component without 'name'");
      continue;
    }
    if (!get(node, "name", name, "a name")) continue;
    if (!valid_name(name)) {
      error(node["name"].Mark(), "component name '" + printable(name) + "' must be 1.." +
                                     std::to_string(kMaxNameLength) + " letters, digits, '_' or '-'");
      continue;
    }
    if (!node["class"]) {
      error(node.Mark(), "component '" + name + "' has no 'class'");
      continue;
    }
    if (!get(node, "class", impl, "a component class name")) continue;
    // A class that is not built in is looked up as a plug-in by its name and loaded
    // (only when files may be opened: --check does, a fuzz run does not).
    std::string why;
    const ComponentClass* cls = options_.open_files ? registry_.resolve(impl, why) : registry_.find(impl);
    if (cls == nullptr) {
      error(node["class"].Mark(),
            why.empty() ? "unknown component class '" + impl + "' (known: " + registry_.names() + ")" : why);
      continue;
    }
    ComponentSettings s;
    s.name = name;
    s.impl = impl;
    s.base_dir = base_dir_;
    int64_t instance = 0;
    get_int_range(node, "instance", 0, 255, instance, "an instance number 0..255");
    s.address = tims::Address::make(host.settings.system, cls->class_id, static_cast<uint8_t>(instance));
    get(node, "autostart", s.autostart, "true or false");
    get_positive_ms(node, "retry_ms", s.retry_ns);
    get_positive_ms(node, "rpc_timeout_ms", s.rpc_timeout_ns);
    if (int64_t retries = 0; get_int_range(node, "rpc_retries", 0, 10, retries, "a number of retries 0..10")) {
      s.rpc_retries = static_cast<uint32_t>(retries);
    }

    std::unique_ptr<Component> component;
    try {
      component = cls->make();
    } catch (const std::exception& e) {
      error(node["class"].Mark(), "cannot construct '" + impl + "': " + e.what());
      continue;
    }
    // What GET_CLASS serves (tools learn the class from it), with the declared values
    // as defaults: before the host file's values are set below.
    try {
      component->class_description_ = encode_class_description(describe_class(*cls, component->parameters()),
                                                               &component->class_description_base_);
    } catch (const std::exception& e) {
      error(node["class"].Mark(), "class '" + impl + "' cannot be described to tools: " + e.what());
      continue;
    }
    const DataTaskMode mode = component->data_task_mode();
    if (const YAML::Node ct = node["command_task"]) {
      if (!ct.IsMap()) error(ct.Mark(), "'command_task' must be a map (priority, cpu, stack_kib, slots)");
      else {
        tasks_.read_task(ct, s.command_task, "command_task", {"slots"});
        int64_t slots = 0;
        if (get_int_range(ct, "slots", 1, 4096, slots, "a slot count")) s.command_slots = static_cast<uint32_t>(slots);
      }
    }
    const YAML::Node dt = node["data_task"];
    if (mode == DataTaskMode::kNone) {
      if (dt) error(dt.Mark(), "class '" + impl + "' has no data task");
    } else if (!dt) {
      if (mode == DataTaskMode::kPeriodic) {
        error(node.Mark(),
              "component '" + name + "': class '" + impl + "' has a periodic data task: give data_task.period_ms");
      }
    } else if (!dt.IsMap()) {
      error(dt.Mark(), "'data_task' must be a map");
    } else {
      std::set<std::string> extra{"ring", "max_listeners", "lease_ms"};
      if (mode == DataTaskMode::kPeriodic) extra.insert({"period_ms", "phase_ms"});
      else extra.insert({"timeout_ms", "input_slots"});
      tasks_.read_task(dt, s.data_task, "data_task of a " + std::string(describe(mode)) + " class", extra, 0);
      int64_t n = 0;
      if (get_int_range(dt, "ring", 2, 1'000'000, n, "a sample count")) s.ring_size = static_cast<uint32_t>(n);
      if (get_int_range(dt, "max_listeners", 1, 1024, n, "a listener count"))
        s.max_listeners = static_cast<uint32_t>(n);
      if (int64_t ns = 0; get_ms_range(dt, "lease_ms", 100, 86'400'000, ns, "a lease in milliseconds")) {
        s.lease_ns = ns;
      }
      if (get_int_range(dt, "input_slots", 1, 4096, n, "a slot count")) s.input_slots = static_cast<uint32_t>(n);
      if (mode == DataTaskMode::kPeriodic) {
        if (!dt["period_ms"]) error(dt.Mark(), "periodic data task without 'period_ms'");
        else get_positive_ms(dt, "period_ms", s.period_ns);
        // Deadlines on a fixed grid of the clock: tasks of one host (or cyclictest
        // --secaligned) in a chosen phase against each other.
        if (double ms = 0; dt["phase_ms"] && get(dt, "phase_ms", ms, "a number of milliseconds")) {
          const auto ns = static_cast<int64_t>(std::llround(ms * 1e6));
          if (!(ms >= 0) || !std::isfinite(ms) || (s.period_ns > 0 && ns >= s.period_ns)) {
            error(dt["phase_ms"].Mark(),
                  "'phase_ms' = " + dt["phase_ms"].Scalar() + " must be at least 0 and below period_ms");
          } else {
            s.phase_ns = ns;
          }
        }
      } else {
        get_positive_ms(dt, "timeout_ms", s.data_timeout_ns);
      }
    }
    // data_task.timeout_ms of a class with declared inputs is the former name of its
    // parameter silence_ms (docs/parameters.md): taken there, with a warning (not for
    // a class whose silence_ms is older than its declared inputs: SilenceParam).
    std::optional<std::pair<std::string, YAML::Node>> old_timeout;
    const auto* consumer = dynamic_cast<const DataComponentBase*>(component.get());
    if (dt && dt.IsMap() && dt["timeout_ms"] && consumer != nullptr && consumer->timeout_is_silence()) {
      old_timeout.emplace("timeout_ms", dt["timeout_ms"]);
    }
    // Parameters.
    Pending p{node, std::move(component), {}};
    ParameterSet& params = p.component->parameters();
    // Relative paths in parameters (declared defaults and the file's values) are the
    // host file's folder's.
    for (std::size_t i = 0; i < params.size(); ++i) {
      if (auto err = params.at(i).set_base_dir(base_dir_)) error(node.Mark(), "component '" + name + "': " + *err);
    }
    std::set<std::string> given;
    std::map<const Parameter*, YAML::Mark> given_marks;
    if (const YAML::Node pn = node["params"]) {
      if (!pn.IsMap()) {
        error(pn.Mark(), "'params' must be a map of parameter: value");
      } else {
        for (auto it = pn.begin(); it != pn.end(); ++it) {
          const std::string key = it->first.Scalar();
          Parameter* param = params.find(key.c_str());
          if (param == nullptr && (param = params.renamed(key)) != nullptr) {
            warn(it->first.Mark(), "component '" + name + "': parameter '" + key + "' is now '" + param->name() +
                                       "' (the old name still works; rename it: docs/parameters.md)");
            if (pn[param->name()]) {
              error(it->first.Mark(), "component '" + name + "': '" + key + "' and '" + param->name() +
                                          "' are the same parameter (old and new name): give one");
              continue;
            }
          }
          if (param == nullptr) {
            error(it->first.Mark(),
                  "unknown parameter '" + key + "' for class '" + impl + "' (known: " + params.names() + ")");
            continue;
          }
          if (!it->second.IsScalar()) {
            error(it->second.Mark(), "parameter '" + key + "' must be a single value");
            continue;
          }
          if (auto err = param->set_from_text(it->second.Scalar())) {
            error(it->second.Mark(), *err);
            continue;
          }
          given.insert(param->name());
          given_marks[param] = it->second.Mark();
          if (param->spec().component_ref) p.refs.emplace_back(param, it->second);
        }
      }
    }
    if (old_timeout && given.count("silence_ms") == 0) {
      const YAML::Node v = old_timeout->second;
      warn(v.Mark(), "component '" + name +
                         "': data_task.timeout_ms is now the parameter silence_ms (params: {silence_ms: " + v.Scalar() +
                         "}; the old name still works: docs/parameters.md)");
      if (auto err = params.find("silence_ms")->set_from_text(v.Scalar())) error(v.Mark(), *err);
      else given_marks[params.find("silence_ms")] = v.Mark();
    }
    // The host's default log level for components that do not set their own.
    if (given.count(Component::kLogLevelParam) == 0) {
      if (Parameter* lp = params.find(Component::kLogLevelParam))
        (void)lp->set_from_text(gdos::describe(host.settings.gdos.level));
    }
    for (std::size_t i = 0; i < params.size(); ++i) {
      const Parameter& prm = params.at(i);
      if (prm.spec().required && given.count(prm.name()) == 0) {
        error(node.Mark(),
              "component '" + name + "': missing required parameter '" + prm.name() + "' (" + prm.spec().doc + ")");
      }
    }
    if (options_.check_paths) paths_.check_parameter_paths(node, name, params, given_marks);
    // The class's own rules for its values (what init() and SET_PARAM check too).
    if (ParameterProblem problem; !p.component->check_parameters(ParameterValues(), problem)) {
      const auto at = problem.parameter != nullptr ? given_marks.find(problem.parameter) : given_marks.end();
      error(at != given_marks.end() ? at->second : node.Mark(),
            "component '" + name + "': parameter '" +
                (problem.parameter != nullptr ? problem.parameter->name() : std::string("?")) + "': " + problem.text);
    }
    if (by_name.count(name) != 0) {
      error(node["name"].Mark(), "duplicate component name '" + name + "'");
      continue;
    }
    if (const auto it = by_address.find(s.address.raw()); it != by_address.end()) {
      error(node.Mark(), "component '" + name + "' has the address " + s.address.str() + " of component '" +
                             pending[it->second].component->name() + "' (give another 'instance')");
      continue;
    }
    p.component->settings_ = s;
    component_addresses_[name] = s.address;
    by_name[name] = pending.size();
    by_address[s.address.raw()] = pending.size();
    pending.push_back(std::move(p));
  }

  // Resolve references; collect dependencies.
  std::vector<std::vector<std::size_t>> deps(pending.size());
  for (std::size_t i = 0; i < pending.size(); ++i) {
    for (auto& [param, vnode] : pending[i].refs) {
      const std::string target = param->get_string();
      tims::Address addr;
      if (const auto it = by_name.find(target); it != by_name.end()) {
        addr = pending[it->second].component->address();
        if (it->second == i) {
          error(vnode.Mark(), "component '" + pending[i].component->name() + "' depends on itself");
          continue;
        }
        if (!param->spec().weak_ref) deps[i].push_back(it->second);
      } else if (const auto parsed = tims::parse_address(target)) {
        addr = *parsed;
        if (const auto it2 = by_address.find(addr.component().raw());
            it2 != by_address.end() && !param->spec().weak_ref) {
          deps[i].push_back(it2->second);
        }
      } else {
        error(vnode.Mark(), "parameter '" + param->name() + "': no component named '" + target +
                                "' in this host file (give a name or an address like Generator(0/1))");
        continue;
      }
      pending[i].component->refs_.emplace_back(param, addr.component());
    }
  }
  // Topological order: dependencies first; a cycle is an error.
  std::vector<int> mark(pending.size(), 0);
  std::vector<std::size_t> order;
  std::function<bool(std::size_t)> visit = [&](std::size_t i) {
    if (mark[i] == 2) return true;
    if (mark[i] == 1) {
      error(pending[i].node.Mark(), "dependency cycle through component '" + pending[i].component->name() + "'");
      return false;
    }
    mark[i] = 1;
    for (std::size_t d : deps[i]) {
      if (!visit(d)) return false;
    }
    mark[i] = 2;
    order.push_back(i);
    return true;
  };
  for (std::size_t i = 0; i < pending.size(); ++i) {
    if (!visit(i)) break;
  }
  if (!report_.errors.empty()) return;
  std::vector<std::size_t> position(pending.size());
  for (std::size_t k = 0; k < order.size(); ++k) position[order[k]] = k;
  host.dependencies.assign(order.size(), {});
  for (std::size_t k = 0; k < order.size(); ++k) {
    for (std::size_t d : deps[order[k]]) host.dependencies[k].push_back(position[d]);
    host.components.push_back(std::move(pending[order[k]].component));
  }
}

}  // namespace rack
