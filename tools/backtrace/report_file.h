// Reading mode-switch report files (written by rack::rt::modeswitch; the format's one
// definition, each line's writer and reader: rack/rt/modeswitch_report.h; described for
// users in tools/backtrace/README.md). Separate from the symbolizer so the parser can be tested
// without binaries.
//
// Real-time contract: a tool; nothing here is RT-safe.
#pragma once

#include <cstdint>
#include <istream>
#include <map>
#include <string>
#include <vector>

namespace rack::backtrace {

struct ModuleLine {
  int id = 0;
  uint64_t base = 0;        // load bias
  uint64_t lo = 0, hi = 0;  // executable range, absolute
  std::string build_id;     // hex, "" when the module had none
  std::string path;
};

struct Report {
  uint64_t sequence = 0;
  std::map<std::string, std::string> fields;  // reason, mode, task, component, label, tid, time_ns, ...
  std::string detail;
  std::vector<uint64_t> pcs;  // call-site PCs (already adjusted), innermost first
  std::string where;          // "file:line" of its first line, for messages
  // Identical reports after it that were counted, not written (`repeat` lines):
  // this report stands for 1 + repeats.
  uint64_t repeats = 0;
  [[nodiscard]] std::string field(const std::string& key) const {
    const auto it = fields.find(key);
    return it == fields.end() ? "" : it->second;
  }
};

struct ReportFile {
  std::string name;
  std::string header;               // the first line
  std::vector<ModuleLine> modules;  // in the order seen (ids index them)
  std::vector<Report> reports;      // complete reports only
  std::vector<std::string> errors;  // "file:line: ..." for truncated or malformed parts
  bool unreadable = false;          // the file could not be read at all (errors says why)
  // The module holding `pc` (absolute), or nullptr.
  [[nodiscard]] const ModuleLine* module_of(uint64_t pc) const;
};

// Limits (tools/backtrace/README.md): a report file is a regular file (a FIFO or device
// is refused without blocking) of at most kMaxReportFileBytes; at most kMaxReportErrors
// errors are listed (one more line says how many were left out).
inline constexpr uint64_t kMaxReportFileBytes = 64u << 20;  // 64 MiB
inline constexpr std::size_t kMaxReportErrors = 100;

// Parses a whole report file. Never throws for bad content: what cannot be read is
// described in `errors` with file and line, and the complete reports are kept.
ReportFile parse_report_file(std::istream& in, const std::string& name);
// The same for the file's text in memory (what a fuzz harness drives).
ReportFile parse_report_text(const std::string& text, const std::string& name);
// Opens and parses `path` ("-": standard input, read up to the same limit). A file that
// cannot be read is one error ("path: ...", with errno's text) and no report.
ReportFile load_report_file(const std::string& path);

}  // namespace rack::backtrace
