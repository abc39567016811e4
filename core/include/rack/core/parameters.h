// Runtime parameters: declared by a component (in its constructor), filled from the
// host file, read and set by message (GET_PARAM / SET_PARAM).
//
// Thread-safety: values are written by the command task (SET_PARAM) or by the
// executor before tasks start (host file), and read by any task. int/float/bool are
// atomics; a string is copied under a seqlock. Declaration is not thread-safe and
// happens before the component is started.
// Real-time contract: get_*(), copy_string(), set_from_wire() and to_record() are
// RT-safe. declare_*() and set_from_text() are not (set-up only).
#pragma once

#include <atomic>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "rack/core/wire.h"

namespace rack {

using wire::ParamKind;
[[nodiscard]] const char* describe(ParamKind kind) noexcept;

// What a string parameter names on this host's file system (Parameter::Spec::path).
// A relative path is relative to the folder of the host file that rackd runs (set
// with ParameterSet::set_base_dir), in the host file and in a SET_PARAM alike: the
// parameter stores it made absolute, so GET_PARAM, the component's messages and the
// tools all show the one file it names. Without a base folder (a component made
// outside a host file) the value is kept as given.
enum class PathRole : uint8_t {
  kNone,
  kInput,      // a file or folder read: `rackd --check` fails when it does not exist
  kOutput,     // a file written: `rackd --check` fails when its folder does not exist
  kOutputDir,  // a folder files are written to: `rackd --check` fails when it does not exist
  kDevice,     // a device (or file) opened when switched on: may appear later, not checked;
               // a value of digits only is a device number, kept as given
};

// `path` made absolute against `base_dir` ("." and leading "./" dropped); `path` itself
// when it is empty or absolute, or `base_dir` is empty. Not RT-safe.
[[nodiscard]] std::string resolve_path(const std::string& base_dir, const std::string& path);

class Parameter {
 public:
  struct Spec {
    std::string doc;        // one line, shown by rackctl params and --list-classes
    bool required = false;  // the host file must give a value
    double min = -std::numeric_limits<double>::infinity();
    double max = std::numeric_limits<double>::infinity();
    bool component_ref = false;  // a string that names a component (dependency)
    // With component_ref: the named component is not a dependency (no start or
    // shutdown order), for a reference back up a pipeline that would otherwise be a
    // cycle (LadarReplay's `pace` names a consumer of its own scans).
    bool weak_ref = false;
    // A string parameter that takes only these values (e.g. gdosLevel); empty: any.
    std::vector<std::string> choices{};
    // Read only by init() (a file to load, a device to open): SET_PARAM refuses to
    // change it (the running component would not see the new value; restart rackd).
    bool init_only = false;
    // Of a number, for tools (rackctl params, the class description): "m", "m/s",
    // "rad", "ms", "Hz"; empty: none, or not a number.
    std::string unit{};
    // A string that names a file, folder or device (PathRole): resolved against the
    // host file's folder, checked by rackd --check.
    PathRole path = PathRole::kNone;
  };

  Parameter(std::string name, ParamKind kind, Spec spec);
  Parameter(const Parameter&) = delete;
  Parameter& operator=(const Parameter&) = delete;

  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] ParamKind kind() const noexcept { return kind_; }
  [[nodiscard]] const Spec& spec() const noexcept { return spec_; }

  // Readers (RT-safe). A getter of the wrong kind returns the converted value
  // (int<->float) or 0/false: kinds are fixed at declaration, so this is a bug.
  [[nodiscard]] int64_t get_int() const noexcept;
  [[nodiscard]] double get_float() const noexcept;
  [[nodiscard]] bool get_bool() const noexcept;
  // Copies the string value (NUL-terminated, cut to `size`). RT-safe.
  void copy_string(char* out, std::size_t size) const noexcept;
  [[nodiscard]] std::string get_string() const;  // not RT-safe

  // From host-file text. nullopt on success, otherwise the reason. Not RT-safe.
  std::optional<std::string> set_from_text(const std::string& text);
  // From a SET_PARAM record (kinds must match; an int is accepted for a float).
  // Returns nullptr on success, otherwise a static reason. RT-safe.
  const char* set_from_wire(const wire::ParamRecord& record) noexcept;
  // The checks of set_from_wire without the store: nullptr when `record` is a valid
  // value of this parameter, then `value` holds it as this parameter's kind (an int
  // given for a float converted). RT-safe.
  const char* check_wire(const wire::ParamRecord& record, wire::ParamRecord& value) const noexcept;
  void to_record(wire::ParamRecord& out) const noexcept;  // RT-safe
  [[nodiscard]] std::string value_text() const;           // not RT-safe

  // The folder a relative path resolves against (absolute; "": none), for a parameter
  // with Spec::path: the present value is resolved at once. Before the tasks start
  // (host file loader). Returns the reason when the resolved path does not fit.
  std::optional<std::string> set_base_dir(const std::string& dir);
  [[nodiscard]] const std::string& base_dir() const noexcept { return base_dir_; }

  [[nodiscard]] bool was_set() const noexcept { return set_.load(std::memory_order_relaxed); }
  // SET_PARAMs taken so far, of a changed value or not: a component that acts on every
  // order (not only on a change) compares it. Acquire: the value written before it is seen.
  [[nodiscard]] uint32_t write_count() const noexcept { return writes_.load(std::memory_order_acquire); }

 private:
  void store_string(const char* text, std::size_t len) noexcept;
  [[nodiscard]] bool is_choice(const char* text) const noexcept;
  // `text` as stored: made absolute against base_dir_ when it is a relative path
  // (Spec::path). False when the result does not fit `out`. RT-safe.
  [[nodiscard]] bool resolve(const char* text, std::size_t len, char (&out)[wire::kParamStringLen]) const noexcept;

  std::string name_;
  ParamKind kind_;
  Spec spec_;
  std::string base_dir_;  // set before the tasks start, then only read
  // Each value is independent; relaxed is enough for int/float/bool: a reader sees
  // the old or the new value, never a torn one.
  std::atomic<int64_t> int_{0};
  std::atomic<double> float_{0.0};
  std::atomic<bool> set_{false};
  std::atomic<uint32_t> writes_{0};  // SET_PARAMs (release after the value is stored)
  // Seqlock for the string: odd while being written. acquire/release pair the
  // sequence with the bytes (the bytes themselves are accessed through atomic_ref).
  std::atomic<uint32_t> string_seq_{0};
  alignas(8) char string_[wire::kParamStringLen] = {};
};

// The parameter values a component's check sees (Component::check_parameters):
// every parameter's current value, except one whose candidate value is being checked
// (a SET_PARAM not yet applied), which shows that. RT-safe reads, no allocation.
class ParameterValues {
 public:
  ParameterValues() noexcept = default;  // the current values
  // `candidate` as checked by Parameter::check_wire (of `changing`'s kind).
  ParameterValues(const Parameter& changing, const wire::ParamRecord& candidate) noexcept
      : changing_(&changing), candidate_(&candidate) {}

  [[nodiscard]] int64_t get_int(const Parameter& p) const noexcept;
  [[nodiscard]] double get_float(const Parameter& p) const noexcept;
  [[nodiscard]] bool get_bool(const Parameter& p) const noexcept;
  void copy_string(const Parameter& p, char* out, std::size_t size) const noexcept;
  [[nodiscard]] const Parameter* changing() const noexcept { return changing_; }

 private:
  const Parameter* changing_ = nullptr;
  const wire::ParamRecord* candidate_ = nullptr;
};

// Why a component refused its parameter values: the parameter at fault (the host
// file reports the error at its line) and the reason. Filled by RT code: fixed size.
struct ParameterProblem {
  const Parameter* parameter = nullptr;
  char text[100] = {};
  // Sets both; `reason` is cut to fit. RT-safe.
  void set(const Parameter& p, const char* reason) noexcept;
};

class ParameterSet {
 public:
  // Declaration (constructor of a component). Not RT-safe. Throws
  // std::invalid_argument on a duplicate or too long name.
  Parameter& declare_int(const std::string& name, int64_t initial, Parameter::Spec spec = {});
  Parameter& declare_float(const std::string& name, double initial, Parameter::Spec spec = {});
  Parameter& declare_bool(const std::string& name, bool initial, Parameter::Spec spec = {});
  Parameter& declare_string(const std::string& name, const std::string& initial, Parameter::Spec spec = {});

  [[nodiscard]] Parameter* find(const char* name) noexcept;  // RT-safe (linear, no allocation)
  [[nodiscard]] const Parameter* find(const char* name) const noexcept;
  [[nodiscard]] std::size_t size() const noexcept { return params_.size(); }
  [[nodiscard]] Parameter& at(std::size_t i) noexcept { return params_[i]; }
  [[nodiscard]] const Parameter& at(std::size_t i) const noexcept { return params_[i]; }
  [[nodiscard]] std::string names() const;  // "a, b, c" for error messages

  // A former name of a parameter (docs/parameters.md): the host file loader accepts
  // it with a warning that names the file, line, key and the new name, so that host
  // files written before the rename keep working; GET_PARAM and SET_PARAM (rackctl
  // set-param, rack-gui) take it too, SET_PARAM with a warning in its OK reply and in
  // the log. Declaration only; not RT-safe.
  void add_old_name(const std::string& old_name, const std::string& new_name);
  // The parameter that `old_name` was renamed to, or nullptr. RT-safe (linear, no
  // allocation).
  [[nodiscard]] Parameter* renamed(const char* old_name) noexcept;
  [[nodiscard]] Parameter* renamed(const std::string& old_name) noexcept { return renamed(old_name.c_str()); }

 private:
  Parameter& add(const std::string& name, ParamKind kind, Parameter::Spec spec);
  std::deque<Parameter> params_;                                // stable addresses
  std::vector<std::pair<std::string, std::string>> old_names_;  // (old, new)
};

}  // namespace rack
