#include "report_file.h"

#include <climits>
#include <cstdint>
#include <iostream>
#include <sstream>

#include "rack/rt/input_file.h"
#include "rack/rt/modeswitch_report.h"

namespace rack::backtrace {

namespace {

namespace format = rack::rt::modeswitch::report;

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
  const std::string expected = std::string(format::kMagic) + " " + std::to_string(format::kVersion);
  if (format::line_kind(line) != format::LineKind::kHeader) {
    errors.push_back(where(1) + ": not a RACK mode-switch report (expected '" + expected + " ...', got '" +
                     line.substr(0, 60) + "')");
    return f;
  }
  format::HeaderLine head;
  if (!format::parse(line, head)) {
    errors.push_back(where(1) + ": malformed header line (expected '" + expected + " program=... pid=...')");
    return f;
  }
  if (head.version != format::kVersion) {
    errors.push_back(where(1) + ": report format version not understood (this tool reads version " +
                     std::to_string(format::kVersion) + ")");
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
    switch (format::line_kind(line)) {
      case format::LineKind::kModule: {
        if (open) close_truncated("a module line follows it");
        format::ModuleLine m;
        if (!format::parse(line, m) || m.id < INT_MIN || m.id > INT_MAX) {
          errors.push_back(where(n) + ": malformed module line");
          continue;
        }
        f.modules.push_back({static_cast<int>(m.id), m.base, m.lo, m.hi, std::string(m.build_id), std::string(m.path)});
        break;
      }
      case format::LineKind::kReport: {
        if (open) close_truncated("the next report starts");
        current = Report{};
        current.where = where(n);
        format::ReportLine r;
        if (!format::parse(line, r)) {
          errors.push_back(where(n) + ": malformed report line");
          continue;
        }
        current.sequence = r.sequence;
        expected_frames = r.frames;
        format::for_each_field(std::string_view(line).substr(format::kReportWord.size()),
                               [&](std::string_view key, std::string_view value) {
                                 current.fields[std::string(key)] = std::string(value);
                               });
        open = true;
        open_line = n;
        break;
      }
      case format::LineKind::kDetail: {
        std::string_view text;
        if (!open || !format::parse_detail(line, text)) {
          errors.push_back(where(n) + ": 'detail' outside a report");
          continue;
        }
        current.detail = std::string(text);
        break;
      }
      case format::LineKind::kFrame: {
        if (!open) {
          errors.push_back(where(n) + ": 'frame' outside a report");
          continue;
        }
        format::FrameLine fr;
        if (!format::parse(line, fr) || fr.index != current.pcs.size()) {
          errors.push_back(where(n) + ": malformed frame line (expected 'frame " + std::to_string(current.pcs.size()) +
                           " 0x...')");
          continue;
        }
        current.pcs.push_back(fr.pc);
        break;
      }
      case format::LineKind::kEnd: {
        uint64_t seq = 0;
        if (!open || !format::parse_end(line, seq) || seq != current.sequence) {
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
        break;
      }
      case format::LineKind::kRepeat: {
        // `repeat FIRST count=N ...`: N more reports identical to report FIRST.
        if (open) close_truncated("a repeat line follows it");
        format::RepeatLine r;
        if (!format::parse(line, r)) {
          errors.push_back(where(n) + ": malformed repeat line");
          continue;
        }
        const auto at = by_sequence.find(r.first);
        if (at != by_sequence.end()) {
          uint64_t& repeats = f.reports[at->second].repeats;
          repeats = r.count > UINT64_MAX - repeats ? UINT64_MAX : repeats + r.count;  // a hostile file saturates
        } else {
          errors.push_back(where(n) + ": repeat of report " + std::to_string(r.first) + ", which is not in the file");
        }
        break;
      }
      case format::LineKind::kHeader:
      case format::LineKind::kOther: errors.push_back(where(n) + ": unknown line '" + line.substr(0, 40) + "'"); break;
    }
  }
  if (open) close_truncated("the file ends: the process died while writing, or the file was cut");
  errors.finish(name);
  return f;
}

}  // namespace

}  // namespace rack::backtrace
