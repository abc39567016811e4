#include "report_file.h"

#include <cerrno>
#include <cstdlib>
#include <iostream>
#include <sstream>

#include "rack/rt/input_file.h"

namespace rack::backtrace {

namespace {

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

// "key=value key=value ..." (values without spaces), from `pos`.
std::map<std::string, std::string> key_values(const std::string& line, std::size_t pos) {
  std::map<std::string, std::string> out;
  std::istringstream in(line.substr(pos));
  std::string word;
  while (in >> word) {
    const auto eq = word.find('=');
    if (eq != std::string::npos) out[word.substr(0, eq)] = word.substr(eq + 1);
  }
  return out;
}

bool parse_u64(const std::string& text, uint64_t& out) {
  if (text.empty()) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtoull(text.c_str(), &end, 0);
  return errno == 0 && end != nullptr && *end == '\0';
}

}  // namespace

const ModuleLine* ReportFile::module_of(uint64_t pc) const {
  for (const auto& m : modules) {
    if (pc >= m.lo && pc < m.hi) return &m;
  }
  return nullptr;
}

namespace {

// The errors list stays short: after kMaxReportErrors only a count is kept.
class ErrorList {
 public:
  explicit ErrorList(std::vector<std::string>& out) : out_(out) {}
  void push_back(std::string e) {
    if (out_.size() < kMaxReportErrors) {
      out_.push_back(std::move(e));
    } else {
      ++dropped_;
    }
  }
  void finish(const std::string& name) {
    if (dropped_ > 0) out_.push_back(name + ": " + std::to_string(dropped_) + " more errors not listed");
  }

 private:
  std::vector<std::string>& out_;
  uint64_t dropped_ = 0;
};

ReportFile parse(std::istream& in, const std::string& name);

}  // namespace

ReportFile parse_report_file(std::istream& in, const std::string& name) {
  try {
    return parse(in, name);
  } catch (const std::exception& e) {  // allocation: refused, never past here
    ReportFile f;
    f.name = name;
    f.errors.push_back(name + ": cannot read the report file: " + e.what());
    return f;
  }
}

ReportFile parse_report_text(const std::string& text, const std::string& name) {
  std::istringstream in(text);
  return parse_report_file(in, name);
}

ReportFile load_report_file(const std::string& path) {
  std::string text, error;
  if (path == "-") {
    // Standard input is whatever the user piped: read with the same limit.
    char chunk[65536];
    while (std::cin.read(chunk, sizeof chunk) || std::cin.gcount() > 0) {
      text.append(chunk, static_cast<std::size_t>(std::cin.gcount()));
      if (text.size() > kMaxReportFileBytes) {
        ReportFile f;
        f.name = "<stdin>";
        f.unreadable = true;
        f.errors.push_back("<stdin>: more than the limit of " + rack::rt::byte_size_text(kMaxReportFileBytes) +
                           " of a report file");
        return f;
      }
    }
    return parse_report_text(text, "<stdin>");
  }
  if (!rack::rt::read_regular_file(path, kMaxReportFileBytes, "report file", text, error)) {
    ReportFile f;
    f.name = path;
    f.unreadable = true;
    f.errors.push_back(error);
    return f;
  }
  return parse_report_text(text, path);
}

namespace {

ReportFile parse(std::istream& in, const std::string& name) {
  ReportFile f;
  f.name = name;
  ErrorList errors(f.errors);
  std::string line;
  int n = 0;
  auto where = [&](int at) { return name + ":" + std::to_string(at); };
  if (!std::getline(in, line)) {
    errors.push_back(name + ": empty (not a RACK mode-switch report)");
    return f;
  }
  n = 1;
  if (!starts_with(line, "RACK-MODESWITCH-REPORT ")) {
    errors.push_back(where(1) + ": not a RACK mode-switch report (expected 'RACK-MODESWITCH-REPORT 1 ...', got '" +
                     line.substr(0, 60) + "')");
    return f;
  }
  if (!starts_with(line, "RACK-MODESWITCH-REPORT 1 ")) {
    errors.push_back(where(1) + ": report format version not understood (this tool reads version 1)");
    return f;
  }
  f.header = line;
  bool open = false;
  Report current;
  uint64_t expected_frames = 0;
  int open_line = 0;
  std::map<uint64_t, std::size_t> by_sequence;  // complete reports: index in f.reports
  auto close_truncated = [&](const std::string& why) {
    errors.push_back(where(open_line) + ": report " + std::to_string(current.sequence) +
                     " is truncated: " + std::to_string(current.pcs.size()) + " of " + std::to_string(expected_frames) +
                     " frames and no 'end " + std::to_string(current.sequence) + "' line (" + why + ")");
    open = false;
  };
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) continue;
    if (starts_with(line, "module ")) {
      if (open) close_truncated("a module line follows it");
      ModuleLine m;
      const auto path_at = line.find(" path=");
      const auto kv = key_values(line.substr(0, path_at), 7);
      std::istringstream id(line.substr(7));
      if (path_at == std::string::npos || !(id >> m.id) || !kv.count("base") || !parse_u64(kv.at("base"), m.base) ||
          !kv.count("lo") || !parse_u64(kv.at("lo"), m.lo) || !kv.count("hi") || !parse_u64(kv.at("hi"), m.hi)) {
        errors.push_back(where(n) + ": malformed module line");
        continue;
      }
      m.build_id = kv.count("build_id") && kv.at("build_id") != "-" ? kv.at("build_id") : "";
      m.path = line.substr(path_at + 6);
      f.modules.push_back(m);
    } else if (starts_with(line, "report ")) {
      if (open) close_truncated("the next report starts");
      current = Report{};
      current.fields = key_values(line, 7);
      current.where = where(n);
      std::istringstream seq(line.substr(7));
      if (!(seq >> current.sequence) || !current.fields.count("reason") || !current.fields.count("frames") ||
          !parse_u64(current.fields.at("frames"), expected_frames)) {
        errors.push_back(where(n) + ": malformed report line");
        continue;
      }
      open = true;
      open_line = n;
    } else if (starts_with(line, "detail ")) {
      if (!open) {
        errors.push_back(where(n) + ": 'detail' outside a report");
        continue;
      }
      current.detail = line.substr(7);
    } else if (starts_with(line, "frame ")) {
      if (!open) {
        errors.push_back(where(n) + ": 'frame' outside a report");
        continue;
      }
      std::istringstream fr(line.substr(6));
      uint64_t index = 0;
      std::string pc_text;
      uint64_t pc = 0;
      if (!(fr >> index >> pc_text) || !parse_u64(pc_text, pc) || index != current.pcs.size()) {
        errors.push_back(where(n) + ": malformed frame line (expected 'frame " + std::to_string(current.pcs.size()) +
                         " 0x...')");
        continue;
      }
      current.pcs.push_back(pc);
    } else if (starts_with(line, "end ")) {
      uint64_t seq = 0;
      if (!open || !parse_u64(line.substr(4), seq) || seq != current.sequence) {
        errors.push_back(where(n) + ": 'end' without its report");
        open = false;
        continue;
      }
      if (current.pcs.size() != expected_frames) {
        errors.push_back(where(open_line) + ": report " + std::to_string(seq) + " has " +
                         std::to_string(current.pcs.size()) + " frames, its header says " +
                         std::to_string(expected_frames));
      } else {
        by_sequence[current.sequence] = f.reports.size();
        f.reports.push_back(current);
      }
      open = false;
    } else if (starts_with(line, "repeat ")) {
      // `repeat FIRST count=N ...`: N more reports identical to report FIRST.
      if (open) close_truncated("a repeat line follows it");
      std::istringstream seq(line.substr(7));
      uint64_t first = 0, count = 0;
      const auto kv = key_values(line, 7);
      if (!(seq >> first) || !kv.count("count") || !parse_u64(kv.at("count"), count)) {
        errors.push_back(where(n) + ": malformed repeat line");
        continue;
      }
      const auto at = by_sequence.find(first);
      if (at != by_sequence.end()) {
        uint64_t& repeats = f.reports[at->second].repeats;
        repeats = count > UINT64_MAX - repeats ? UINT64_MAX : repeats + count;  // a hostile file saturates
      } else {
        errors.push_back(where(n) + ": repeat of report " + std::to_string(first) + ", which is not in the file");
      }
    } else {
      errors.push_back(where(n) + ": unknown line '" + line.substr(0, 40) + "'");
    }
  }
  if (open) close_truncated("the file ends: the process died while writing, or the file was cut");
  errors.finish(name);
  return f;
}

}  // namespace

}  // namespace rack::backtrace
