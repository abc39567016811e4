// rack-backtrace: symbolizes mode-switch and crash reports (Xenomai's slackspot for
// RACK-RT). Each PC of a report is mapped to its module through the load addresses
// the report recorded (PIE and ASLR), the module's file is checked against the build
// id the report recorded, and libdw (elfutils) gives function, file:line and the
// inlined frames.
#include <cxxabi.h>
#include <elfutils/libdw.h>
#include <elfutils/libdwfl.h>
#include <dwarf.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "rack/rt/input_file.h"
#include "report_file.h"
#include "rack/version.h"

namespace {

using rack::backtrace::ModuleLine;
using rack::backtrace::Report;
using rack::backtrace::ReportFile;

constexpr const char* kUsage = R"(usage: rack-backtrace [options] [REPORT...]

Symbolizes RACK-RT mode-switch and crash reports (the files rackd writes to its
crash directory, <crash_dir>/rackd-<pid>.report; '-' or no file: standard input).
For each report: reason, task, component, what happened, then every frame as
function, file:line, with inlined frames, resolved with libdw against the very
binaries that ran (their build ids are checked; PIE/ASLR load addresses come from
the report).

filters (a report is shown when it matches all given; values may repeat a filter,
and a report matches when any value does):
  --reason R        SYSCALL, FAULT, ALLOC, PRIOINV, WATCHDOG, NOMLOCK, RUSAGE, CRASH
  --task T          task name, e.g. demo:cmd, demo:data
  --component C     component name from the host file
  --function TEXT   some frame's function contains TEXT
  --file TEXT       some frame's source file contains TEXT
options:
  --summary         group identical backtraces (reason, task, frames) with counts,
                    most frequent first
  --root DIR        look for the binaries under DIR (reports copied from a robot)
  -h, --help        this text
  --version         the version (CMake project version, git describe)

exit codes: 0 every report read and symbolized, 1 a report was truncated or malformed
or a binary is missing or does not match its build id (the rest is still printed),
2 usage error or unreadable file.
)";

struct Frame {
  uint64_t pc = 0;
  std::string function;  // demangled; "??" when unknown
  std::string file;      // "" when no line information
  int line = 0;
  bool inlined = false;  // an inlined call inside the next frame's function
  std::string module;    // basename+offset
};

std::string demangle(const char* name) {
  if (name == nullptr) return "??";
  int status = 0;
  std::unique_ptr<char, decltype(&std::free)> d(abi::__cxa_demangle(name, nullptr, nullptr, &status), &std::free);
  return status == 0 && d ? std::string(d.get()) : std::string(name);
}

std::string hex(uint64_t v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%llx", static_cast<unsigned long long>(v));
  return buf;
}

std::string basename_of(const std::string& path) {
  const auto slash = path.rfind('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

// Largest module file handed to libdwfl (a binary with its debug information).
constexpr uint64_t kMaxModuleBytes = 4ull << 30;

// One libdwfl session per report file: its modules at the recorded load biases.
class Symbolizer {
 public:
  Symbolizer(const ReportFile& file, const std::string& root, std::vector<std::string>& errors) : file_(file) {
    static char* debuginfo_path = nullptr;
    static const Dwfl_Callbacks kCallbacks = {dwfl_build_id_find_elf, dwfl_standard_find_debuginfo,
                                              dwfl_offline_section_address, &debuginfo_path};
    dwfl_ = dwfl_begin(&kCallbacks);
    if (dwfl_ == nullptr) {
      errors.push_back(std::string("libdw: ") + dwfl_errmsg(-1));
      return;
    }
    dwfl_report_begin(dwfl_);
    for (const auto& m : file.modules) {
      if (m.path.empty() || m.path[0] != '/') continue;  // linux-vdso.so.1 and the like
      const std::string path = root + m.path;
      // libdwfl opens the file itself, blocking: a report names any path (it may come
      // from another machine), and a FIFO there hung rack-backtrace in open().
      std::string refused;
      if (!rack::rt::check_regular_file(path, kMaxModuleBytes, "module file", refused)) {
        errors.push_back(file.name + ": module " + std::to_string(m.id) + ": " + refused +
                         " (frames in it stay unsymbolized)");
        continue;
      }
      Dwfl_Module* mod = dwfl_report_elf(dwfl_, m.path.c_str(), path.c_str(), -1, m.base, false);
      if (mod == nullptr) {
        errors.push_back(file.name + ": module " + std::to_string(m.id) + " " + path +
                         ": cannot open: " + dwfl_errmsg(-1) + " (frames in it stay unsymbolized)");
        continue;
      }
      const unsigned char* bits = nullptr;
      GElf_Addr vaddr = 0;
      const int len = dwfl_module_build_id(mod, &bits, &vaddr);
      std::string have;
      for (int k = 0; k < len; ++k) {
        char b[3];
        std::snprintf(b, sizeof b, "%02x", bits[k]);
        have += b;
      }
      if (!m.build_id.empty() && have != m.build_id) {
        errors.push_back(file.name + ": module " + std::to_string(m.id) + " " + path + " does not match the report: " +
                         "build id " + (have.empty() ? std::string("none") : have) + ", the report has " + m.build_id +
                         " (the binary was rebuilt or replaced since; symbolize with the binaries that ran, e.g. "
                         "--root DIR with a copy)");
        mismatched_.push_back(m.id);
      }
    }
    dwfl_report_end(dwfl_, nullptr, nullptr);
  }
  ~Symbolizer() {
    if (dwfl_ != nullptr) dwfl_end(dwfl_);
  }
  Symbolizer(const Symbolizer&) = delete;
  Symbolizer& operator=(const Symbolizer&) = delete;

  // The frames of one PC: inlined calls first (innermost), then the function.
  std::vector<Frame> frames(uint64_t pc) const {
    std::vector<Frame> out;
    const ModuleLine* m = file_.module_of(pc);
    const std::string where = m != nullptr ? basename_of(m->path) + "+" + hex(pc - m->base) : hex(pc);
    Dwfl_Module* mod = dwfl_ != nullptr ? dwfl_addrmodule(dwfl_, pc) : nullptr;
    if (mod == nullptr ||
        (m != nullptr && std::find(mismatched_.begin(), mismatched_.end(), m->id) != mismatched_.end())) {
      out.push_back(Frame{pc, "??", "", 0, false, where});
      return out;
    }
    const std::string symbol = demangle(dwfl_module_addrname(mod, pc));
    std::string file;
    int line = 0;
    if (Dwfl_Line* l = dwfl_module_getsrc(mod, pc)) {
      int col = 0;
      if (const char* src = dwfl_lineinfo(l, nullptr, &line, &col, nullptr, nullptr)) file = src;
    }
    Dwarf_Addr bias = 0;
    Dwarf_Die* cu = dwfl_module_addrdie(mod, pc, &bias);
    Dwarf_Die* scopes = nullptr;
    int n = cu != nullptr ? dwarf_getscopes(cu, pc - bias, &scopes) : 0;
    if (n > 0) {
      // dwarf_getscopes follows an inlined function's abstract origin (where it was
      // written); its physical nesting (where it was inlined) comes from the concrete
      // DIE, as eu-addr2line -i does it.
      Dwarf_Addr dwarf_bias = 0;
      Dwarf_Die concrete;
      Dwarf* dbg = dwfl_module_getdwarf(mod, &dwarf_bias);
      const bool found = dbg != nullptr && dwarf_offdie(dbg, dwarf_dieoffset(&scopes[0]), &concrete) != nullptr;
      free(scopes);
      scopes = nullptr;
      n = found ? dwarf_getscopes_die(&concrete, &scopes) : 0;
    }
    Dwarf_Files* files = nullptr;
    size_t nfiles = 0;
    if (cu != nullptr) dwarf_getsrcfiles(cu, &files, &nfiles);
    // Walk out from the innermost scope: each inlined subroutine is a frame whose
    // location is the current one; its call site becomes the location of the next.
    for (int i = 0; i < n; ++i) {
      Dwarf_Die* s = &scopes[i];
      const int tag = dwarf_tag(s);
      if (tag != DW_TAG_inlined_subroutine && tag != DW_TAG_subprogram) continue;
      if (tag == DW_TAG_subprogram) break;
      Dwarf_Attribute attr;
      const char* linkage = nullptr;
      if (dwarf_attr_integrate(s, DW_AT_linkage_name, &attr) != nullptr) linkage = dwarf_formstring(&attr);
      const char* plain = dwarf_diename(s);
      out.push_back(Frame{pc, linkage != nullptr ? demangle(linkage) : (plain != nullptr ? plain : "??"), file, line,
                          true, where});
      Dwarf_Word call_file = 0, call_line = 0;
      if (dwarf_formudata(dwarf_attr(s, DW_AT_call_file, &attr), &call_file) == 0 && files != nullptr) {
        const char* f = dwarf_filesrc(files, call_file, nullptr, nullptr);
        file = f != nullptr ? f : "";
      }
      if (dwarf_formudata(dwarf_attr(s, DW_AT_call_line, &attr), &call_line) == 0) line = static_cast<int>(call_line);
    }
    free(scopes);
    out.push_back(Frame{pc, symbol, file, line, false, where});
    return out;
  }

 private:
  const ReportFile& file_;
  Dwfl* dwfl_ = nullptr;
  std::vector<int> mismatched_;
};

struct Options {
  std::vector<std::string> reasons, tasks, components, functions, files;
  bool summary = false;
  std::string root;
  std::vector<std::string> inputs;
};

bool any_equal(const std::vector<std::string>& wanted, const std::string& value) {
  return wanted.empty() || std::find(wanted.begin(), wanted.end(), value) != wanted.end();
}

bool frames_match(const std::vector<std::string>& wanted, const std::vector<Frame>& frames, bool by_file) {
  if (wanted.empty()) return true;
  for (const auto& w : wanted) {
    for (const auto& f : frames) {
      if ((by_file ? f.file : f.function).find(w) != std::string::npos) return true;
    }
  }
  return false;
}

std::string frame_text(const Frame& f, int index) {
  std::string s = "    #" + std::to_string(index) + (index < 10 ? "  " : " ");
  s += f.inlined ? "[inlined] " : "";
  s += f.function;
  if (!f.file.empty()) s += " at " + f.file + ":" + std::to_string(f.line);
  s += "  (" + f.module + ")";
  return s;
}

std::string head_text(const Report& r) {
  std::string s = "[" + r.field("reason") + "] task " + r.field("task");
  const std::string comp = r.field("component");
  if (!comp.empty() && comp != "-") s += ", component " + comp + " " + r.field("label");
  s += ", tid " + r.field("tid") + ", mode " + r.field("mode") + ", report " + std::to_string(r.sequence);
  return s;
}

int run(const Options& o) {
  bool problems = false;
  struct Group {
    std::string head;
    std::string detail;
    std::vector<std::string> frames;
    uint64_t count = 0;
  };
  std::map<std::string, Group> groups;
  std::vector<std::string> order;
  uint64_t shown = 0, total = 0;
  for (const auto& input : o.inputs) {
    // A regular file within the limit (a FIFO or device is refused, never waited on).
    const ReportFile file = rack::backtrace::load_report_file(input);
    if (file.unreadable) {
      std::fprintf(stderr, "rack-backtrace: %s\n", file.errors.front().c_str());
      return 2;
    }
    std::vector<std::string> errors = file.errors;
    Symbolizer sym(file, o.root, errors);
    for (const auto& e : errors) std::fprintf(stderr, "rack-backtrace: %s\n", e.c_str());
    problems = problems || !errors.empty();
    for (const auto& r : file.reports) {
      total += 1 + r.repeats;  // identical reports counted, not written
      if (!any_equal(o.reasons, r.field("reason")) || !any_equal(o.tasks, r.field("task")) ||
          !any_equal(o.components, r.field("component"))) {
        continue;
      }
      std::vector<Frame> frames;
      for (uint64_t pc : r.pcs) {
        for (auto& f : sym.frames(pc)) frames.push_back(std::move(f));
      }
      if (!frames_match(o.functions, frames, false) || !frames_match(o.files, frames, true)) continue;
      shown += 1 + r.repeats;
      std::vector<std::string> lines;
      for (std::size_t k = 0; k < frames.size(); ++k) lines.push_back(frame_text(frames[k], static_cast<int>(k)));
      if (!o.summary) {
        std::printf("%s: %s\n    %s\n", r.where.c_str(), head_text(r).c_str(), r.detail.c_str());
        if (r.repeats > 0) {
          std::printf("    and %llu identical report(s) after it (counted, not written)\n",
                      static_cast<unsigned long long>(r.repeats));
        }
        for (const auto& l : lines) std::printf("%s\n", l.c_str());
        std::printf("\n");
        continue;
      }
      // Identical backtraces: same reason, task and symbolized frames (addresses of
      // data, such as a fault address, may differ).
      std::string key = r.field("reason") + "|" + r.field("task");
      for (const auto& f : frames) key += "|" + f.function + "@" + f.file + ":" + std::to_string(f.line);
      auto [it, fresh] = groups.try_emplace(key);
      if (fresh) {
        it->second.head = "[" + r.field("reason") + "] task " + r.field("task") +
                          (r.field("component").empty() || r.field("component") == "-"
                               ? std::string()
                               : ", component " + r.field("component") + " " + r.field("label"));
        it->second.detail = r.detail;
        it->second.frames = lines;
        order.push_back(key);
      }
      it->second.count += 1 + r.repeats;
    }
  }
  if (o.summary) {
    std::stable_sort(order.begin(), order.end(),
                     [&](const std::string& a, const std::string& b) { return groups[a].count > groups[b].count; });
    for (const auto& k : order) {
      const Group& g = groups[k];
      std::printf("%llu x %s\n    %s (first of them)\n", static_cast<unsigned long long>(g.count), g.head.c_str(),
                  g.detail.c_str());
      for (const auto& l : g.frames) std::printf("%s\n", l.c_str());
      std::printf("\n");
    }
    std::printf("%llu report(s) in %zu group(s); %llu report(s) read\n", static_cast<unsigned long long>(shown),
                order.size(), static_cast<unsigned long long>(total));
  }
  return problems ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](std::vector<std::string>& into) {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "rack-backtrace: %s needs a value\n%s", a.c_str(), kUsage);
        std::exit(2);
      }
      into.push_back(argv[++i]);
    };
    if (a == "-h" || a == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    }
    if (a == "--version") {
      rack::print_version("rack-backtrace");
      return 0;
    }
    if (a == "--summary") o.summary = true;
    else if (a == "--reason") {
      value(o.reasons);
      static const char* const kReasons[] = {"SYSCALL",  "FAULT",   "ALLOC",  "PRIOINV",
                                             "WATCHDOG", "NOMLOCK", "RUSAGE", "CRASH"};
      if (std::none_of(std::begin(kReasons), std::end(kReasons),
                       [&](const char* r) { return o.reasons.back() == r; })) {
        std::fprintf(stderr,
                     "rack-backtrace: unknown reason '%s' (SYSCALL, FAULT, ALLOC, PRIOINV, WATCHDOG, NOMLOCK, "
                     "RUSAGE, CRASH)\n",
                     o.reasons.back().c_str());
        return 2;
      }
    } else if (a == "--task") value(o.tasks);
    else if (a == "--component") value(o.components);
    else if (a == "--function") value(o.functions);
    else if (a == "--file") value(o.files);
    else if (a == "--root") {
      std::vector<std::string> r;
      value(r);
      o.root = r.back();
      while (!o.root.empty() && o.root.back() == '/') o.root.pop_back();
    } else if (a.size() > 1 && a[0] == '-') {
      std::fprintf(stderr, "rack-backtrace: unknown option '%s'\n%s", a.c_str(), kUsage);
      return 2;
    } else {
      o.inputs.push_back(a);
    }
  }
  if (o.inputs.empty()) {
    o.inputs.push_back("-");
    // Run by hand without a file it waits for a report on the terminal: say so.
    if (::isatty(STDIN_FILENO) != 0) {
      std::fprintf(stderr,
                   "rack-backtrace: no report file given: reading a report from standard input (Ctrl-D ends it);\n"
                   "  rack-backtrace /var/tmp/rack/rackd-PID.report (rackd's crash_dir) for a file, --help for more\n");
    }
  }
  return run(o);
}
