#include "rack/core/parameters.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string_view>

namespace rack {

namespace {
// "./a" -> "a", "." -> "": what is left of a relative path once its folder is known.
std::string_view strip_dot(std::string_view rest) noexcept {
  for (;;) {
    if (rest == ".") return {};
    if (!rest.starts_with("./")) return rest;
    rest.remove_prefix(2);
    while (rest.starts_with('/')) rest.remove_prefix(1);
  }
}
}  // namespace

std::string resolve_path(const std::string& base_dir, const std::string& path) {
  if (path.empty() || path.front() == '/' || base_dir.empty()) return path;
  const std::string_view rest = strip_dot(path);
  std::string out = base_dir;
  if (!rest.empty()) {
    if (out.back() != '/') out += '/';
    out += rest;
  }
  return out;
}

Parameter::Parameter(std::string name, ParamKind kind, Spec spec)
    : name_(std::move(name)), kind_(kind), spec_(std::move(spec)) {}

int64_t Parameter::get_int() const noexcept {
  if (kind_ == ParamKind::kFloat) return static_cast<int64_t>(float_.load(std::memory_order_relaxed));
  return int_.load(std::memory_order_relaxed);
}

double Parameter::get_float() const noexcept {
  if (kind_ == ParamKind::kFloat) return float_.load(std::memory_order_relaxed);
  return static_cast<double>(int_.load(std::memory_order_relaxed));
}

bool Parameter::get_bool() const noexcept { return int_.load(std::memory_order_relaxed) != 0; }

void Parameter::store_string(const char* text, std::size_t len) noexcept {
  if (len >= sizeof string_) len = sizeof string_ - 1;
  const uint32_t seq = string_seq_.load(std::memory_order_relaxed);
  string_seq_.store(seq + 1, std::memory_order_relaxed);  // odd: writing
  std::atomic_thread_fence(std::memory_order_release);
  for (std::size_t i = 0; i < sizeof string_; ++i) {
    std::atomic_ref<char>(string_[i]).store(i < len ? text[i] : '\0', std::memory_order_relaxed);
  }
  string_seq_.store(seq + 2, std::memory_order_release);  // even: stable
}

void Parameter::copy_string(char* out, std::size_t size) const noexcept {
  if (size == 0) return;
  auto* self = const_cast<Parameter*>(this);  // atomic_ref needs non-const storage
  for (;;) {
    const uint32_t before = string_seq_.load(std::memory_order_acquire);
    if ((before & 1u) != 0) continue;  // a writer is mid-update (bounded: one short copy)
    std::size_t i = 0;
    for (; i + 1 < size && i < sizeof string_; ++i) {
      out[i] = std::atomic_ref<char>(self->string_[i]).load(std::memory_order_relaxed);
      if (out[i] == '\0') break;
    }
    if (i + 1 >= size || i >= sizeof string_) out[size - 1 < i ? size - 1 : i] = '\0';
    std::atomic_thread_fence(std::memory_order_acquire);
    if (string_seq_.load(std::memory_order_relaxed) == before) return;
  }
}

bool Parameter::resolve(const char* text, std::size_t len, char (&out)[wire::kParamStringLen]) const noexcept {
  // RT-safe: string_views over the value and base_dir_ (set-up data), copies into `out`.
  std::string_view rest(text, len);
  const bool relative = spec_.path != PathRole::kNone && !base_dir_.empty() && !rest.empty() && rest.front() != '/' &&
                        !(spec_.path == PathRole::kDevice &&
                          rest.find_first_not_of("0123456789") == std::string_view::npos);
  std::size_t n = 0;
  const auto put = [&](std::string_view part) noexcept {
    if (n + part.size() >= sizeof out) return false;
    std::memcpy(out + n, part.data(), part.size());
    n += part.size();
    return true;
  };
  if (relative) {
    rest = strip_dot(rest);
    if (!put(base_dir_)) return false;
    if (!rest.empty() && ((base_dir_.back() != '/' && !put("/")) || !put(rest))) return false;
  } else if (!put(rest)) {
    return false;
  }
  out[n] = '\0';
  return true;
}

std::optional<std::string> Parameter::set_base_dir(const std::string& dir) {
  base_dir_ = dir;
  if (kind_ != ParamKind::kString || spec_.path == PathRole::kNone) return std::nullopt;
  const std::string value = get_string();
  char buf[wire::kParamStringLen] = {};
  if (!resolve(value.data(), value.size(), buf)) {
    return "parameter '" + name_ + "': the path " + resolve_path(base_dir_, value) + " is longer than " +
           std::to_string(wire::kParamStringLen - 1) + " characters";
  }
  store_string(buf, strnlen(buf, sizeof buf));
  return std::nullopt;
}

std::string Parameter::get_string() const {
  char buf[wire::kParamStringLen];
  copy_string(buf, sizeof buf);
  return buf;
}

namespace {
bool in_range(double v, const Parameter::Spec& s) { return v >= s.min && v <= s.max; }
std::string range_text(const Parameter::Spec& s) {
  auto fmt = [](double d) {
    if (std::isinf(d)) return std::string(d < 0 ? "-inf" : "inf");
    std::string t = std::to_string(d);
    while (t.size() > 1 && t.back() == '0') t.pop_back();
    if (!t.empty() && t.back() == '.') t.pop_back();
    return t;
  };
  std::string out = "[";
  out += fmt(s.min);
  out += ", ";
  out += fmt(s.max);
  out += ']';
  return out;
}
}  // namespace

std::optional<std::string> Parameter::set_from_text(const std::string& text) {
  switch (kind_) {
    case ParamKind::kInt: {
      errno = 0;
      char* end = nullptr;
      const long long v = std::strtoll(text.c_str(), &end, 0);
      if (text.empty() || *end != '\0' || errno == ERANGE) {
        return "parameter '" + name_ + "' expects an int, got '" + text + "'";
      }
      if (!in_range(static_cast<double>(v), spec_)) {
        return "parameter '" + name_ + "' = " + text + " is outside " + range_text(spec_);
      }
      int_.store(v, std::memory_order_relaxed);
      break;
    }
    case ParamKind::kFloat: {
      errno = 0;
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (text.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v)) {
        return "parameter '" + name_ + "' expects a float, got '" + text + "'";
      }
      if (!in_range(v, spec_)) {
        return "parameter '" + name_ + "' = " + text + " is outside " + range_text(spec_);
      }
      float_.store(v, std::memory_order_relaxed);
      break;
    }
    case ParamKind::kBool: {
      if (text == "true" || text == "on" || text == "yes") {
        int_.store(1, std::memory_order_relaxed);
      } else if (text == "false" || text == "off" || text == "no") {
        int_.store(0, std::memory_order_relaxed);
      } else {
        return "parameter '" + name_ + "' expects a bool (true/false), got '" + text + "'";
      }
      break;
    }
    case ParamKind::kString: {
      if (!spec_.choices.empty() && !is_choice(text.c_str())) {
        std::string list;
        for (const auto& c : spec_.choices) list += (list.empty() ? "" : ", ") + c;
        return "parameter '" + name_ + "' must be one of " + list + ", got '" + text + "'";
      }
      if (text.size() >= wire::kParamStringLen) {
        return "parameter '" + name_ + "' is longer than " + std::to_string(wire::kParamStringLen - 1) + " characters";
      }
      char buf[wire::kParamStringLen] = {};
      if (!resolve(text.data(), text.size(), buf)) {
        // A relative path fitted, the absolute one it names (against the host file's folder) does not.
        return "parameter '" + name_ + "': the path " + resolve_path(base_dir_, text) + " is longer than " +
               std::to_string(wire::kParamStringLen - 1) +
               " characters (a relative path is taken from the host file's folder)";
      }
      store_string(buf, strnlen(buf, sizeof buf));
      break;
    }
  }
  set_.store(true, std::memory_order_relaxed);
  return std::nullopt;
}

const char* Parameter::check_wire(const wire::ParamRecord& r, wire::ParamRecord& value) const noexcept {
  const auto kind = static_cast<ParamKind>(r.kind);
  value = wire::ParamRecord{};
  std::memcpy(value.name, r.name, sizeof value.name);
  value.kind = static_cast<uint8_t>(kind_);
  switch (kind_) {
    case ParamKind::kInt:
      if (kind != ParamKind::kInt) return "type mismatch: parameter is an int";
      if (!in_range(static_cast<double>(r.int_value), spec_)) return "value out of range";
      value.int_value = r.int_value;
      break;
    case ParamKind::kFloat: {
      double v = 0;
      if (kind == ParamKind::kFloat) v = r.float_value;
      else if (kind == ParamKind::kInt) v = static_cast<double>(r.int_value);
      else return "type mismatch: parameter is a float";
      if (!std::isfinite(v) || !in_range(v, spec_)) return "value out of range";
      value.float_value = v;
      break;
    }
    case ParamKind::kBool:
      if (kind != ParamKind::kBool) return "type mismatch: parameter is a bool";
      if (r.int_value != 0 && r.int_value != 1) return "a bool is 0 or 1";
      value.int_value = r.int_value;
      break;
    case ParamKind::kString: {
      if (kind != ParamKind::kString) return "type mismatch: parameter is a string";
      if (spec_.component_ref) return "a component reference cannot change at run time";
      const std::size_t len = strnlen(r.string_value, sizeof r.string_value);
      if (len == sizeof r.string_value) return "string not terminated";
      if (!spec_.choices.empty() && !is_choice(r.string_value)) return "not one of the allowed values";
      // A relative path is taken from the host file's folder, as in the host file.
      if (!resolve(r.string_value, len, value.string_value)) {
        return "the path made absolute (against the host file's folder) is longer than 127 characters";
      }
      break;
    }
  }
  return nullptr;
}

const char* Parameter::set_from_wire(const wire::ParamRecord& r) noexcept {
  wire::ParamRecord v;
  if (const char* why = check_wire(r, v)) return why;
  switch (kind_) {
    case ParamKind::kInt:
    case ParamKind::kBool: int_.store(v.int_value, std::memory_order_relaxed); break;
    case ParamKind::kFloat: float_.store(v.float_value, std::memory_order_relaxed); break;
    case ParamKind::kString: store_string(v.string_value, strnlen(v.string_value, sizeof v.string_value)); break;
  }
  set_.store(true, std::memory_order_relaxed);
  writes_.fetch_add(1, std::memory_order_release);
  return nullptr;
}

bool Parameter::is_choice(const char* text) const noexcept {
  // RT-safe: compares against strings made at declaration; allocates nothing.
  for (const auto& c : spec_.choices) {
    if (std::strcmp(c.c_str(), text) == 0) return true;
  }
  return false;
}

void Parameter::to_record(wire::ParamRecord& out) const noexcept {
  out = wire::ParamRecord{};
  wire::copy_text(out.name, name_.c_str());  // name_ is set-up data: reading it is RT-safe
  out.kind = static_cast<uint8_t>(kind_);
  out.flags = spec_.component_ref ? 1 : 0;
  switch (kind_) {
    case ParamKind::kInt:
    case ParamKind::kBool: out.int_value = int_.load(std::memory_order_relaxed); break;
    case ParamKind::kFloat: out.float_value = float_.load(std::memory_order_relaxed); break;
    case ParamKind::kString: copy_string(out.string_value, sizeof out.string_value); break;
  }
}

std::string Parameter::value_text() const {
  switch (kind_) {
    case ParamKind::kInt: return std::to_string(get_int());
    case ParamKind::kFloat: {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.17g", get_float());
      return buf;
    }
    case ParamKind::kBool: return get_bool() ? "true" : "false";
    case ParamKind::kString: return get_string();
  }
  return "";
}

int64_t ParameterValues::get_int(const Parameter& p) const noexcept {
  if (&p != changing_) return p.get_int();
  return p.kind() == ParamKind::kFloat ? static_cast<int64_t>(candidate_->float_value) : candidate_->int_value;
}

double ParameterValues::get_float(const Parameter& p) const noexcept {
  if (&p != changing_) return p.get_float();
  return p.kind() == ParamKind::kFloat ? candidate_->float_value : static_cast<double>(candidate_->int_value);
}

bool ParameterValues::get_bool(const Parameter& p) const noexcept {
  if (&p != changing_) return p.get_bool();
  return candidate_->int_value != 0;
}

void ParameterValues::copy_string(const Parameter& p, char* out, std::size_t size) const noexcept {
  if (&p != changing_) return p.copy_string(out, size);
  if (size == 0) return;
  const std::size_t len = strnlen(candidate_->string_value, sizeof candidate_->string_value);
  const std::size_t n = len < size - 1 ? len : size - 1;
  std::memcpy(out, candidate_->string_value, n);
  out[n] = '\0';
}

void ParameterProblem::set(const Parameter& p, const char* reason) noexcept {
  parameter = &p;
  wire::copy_text(text, reason);
}

Parameter& ParameterSet::add(const std::string& name, ParamKind kind, Parameter::Spec spec) {
  if (name.empty() || name.size() >= wire::kParamNameLen) {
    throw std::invalid_argument("parameter name '" + name + "' must have 1 to " +
                                std::to_string(wire::kParamNameLen - 1) + " characters");
  }
  if (find(name.c_str()) != nullptr) throw std::invalid_argument("parameter '" + name + "' declared twice");
  return params_.emplace_back(name, kind, std::move(spec));
}

Parameter& ParameterSet::declare_int(const std::string& name, int64_t initial, Parameter::Spec spec) {
  Parameter& p = add(name, ParamKind::kInt, std::move(spec));
  wire::ParamRecord r;
  r.kind = static_cast<uint8_t>(ParamKind::kInt);
  r.int_value = initial;
  (void)p.set_from_wire(r);
  return p;
}

Parameter& ParameterSet::declare_float(const std::string& name, double initial, Parameter::Spec spec) {
  Parameter& p = add(name, ParamKind::kFloat, std::move(spec));
  wire::ParamRecord r;
  r.kind = static_cast<uint8_t>(ParamKind::kFloat);
  r.float_value = initial;
  (void)p.set_from_wire(r);
  return p;
}

Parameter& ParameterSet::declare_bool(const std::string& name, bool initial, Parameter::Spec spec) {
  Parameter& p = add(name, ParamKind::kBool, std::move(spec));
  (void)p.set_from_text(initial ? "true" : "false");
  return p;
}

Parameter& ParameterSet::declare_string(const std::string& name, const std::string& initial, Parameter::Spec spec) {
  Parameter& p = add(name, ParamKind::kString, std::move(spec));
  if (auto err = p.set_from_text(initial)) throw std::invalid_argument(*err);
  return p;
}

Parameter* ParameterSet::find(const char* name) noexcept {
  for (auto& p : params_) {
    if (std::strncmp(p.name().c_str(), name, wire::kParamNameLen) == 0) return &p;
  }
  return nullptr;
}

const Parameter* ParameterSet::find(const char* name) const noexcept {
  return const_cast<ParameterSet*>(this)->find(name);
}

void ParameterSet::add_old_name(const std::string& old_name, const std::string& new_name) {
  if (find(old_name.c_str()) != nullptr || find(new_name.c_str()) == nullptr) {
    throw std::invalid_argument("old parameter name '" + old_name + "' for '" + new_name +
                                "': the old name is in use or the new one is not declared");
  }
  old_names_.emplace_back(old_name, new_name);
}

Parameter* ParameterSet::renamed(const char* old_name) noexcept {
  for (const auto& [from, to] : old_names_) {
    if (std::strncmp(from.c_str(), old_name, wire::kParamNameLen) == 0) return find(to.c_str());
  }
  return nullptr;
}

std::string ParameterSet::names() const {
  std::string s;
  for (const auto& p : params_) {
    if (!s.empty()) s += ", ";
    s += p.name();
  }
  return s.empty() ? "none" : s;
}

}  // namespace rack
