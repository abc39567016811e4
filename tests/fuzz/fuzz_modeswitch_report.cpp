// libFuzzer harness: mode-switch report files (rack::backtrace::parse_report_text, what
// rack-backtrace reads, and the line readers of rack/rt/modeswitch_report.h under it).
// Invariants: every complete report has exactly the frames its header announced; the
// error list stays within its limit; errors name the file; a line that a reader of the
// format accepts, written again by its writer, reads back with the same fields.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   tools/backtrace/report_file.cpp core/rt/src/input_file.cpp core/rt/src/modeswitch_report.cpp;
//   -Itools/backtrace -Icore/rt/include -Icore/rt/src.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>
#include <vector>

#include "rack/rt/modeswitch_report.h"
#include "report_file.h"

namespace {

namespace fmt = rack::rt::modeswitch::report;

// A word field as the writer puts it (an empty one as kNone).
std::string_view written_word(std::string_view v) { return v.empty() ? fmt::kNone : v; }

template <typename Line>
bool rewritten(const Line& l, std::vector<char>& buf, Line& back) {
  const std::size_t n = fmt::format(l, buf.data(), buf.size());
  if (n == 0 || buf[n - 1] != '\n') return false;
  return fmt::parse(std::string_view(buf.data(), n - 1), back);
}

// One line through reader, writer and reader again: the fields must survive.
void round_trip(std::string_view line) {
  std::vector<char> buf(line.size() * 2 + 512);
  if (fmt::ReportLine r, back; fmt::parse(line, r)) {
    if (!rewritten(r, buf, back) || back.sequence != r.sequence || back.reason != written_word(r.reason) ||
        back.mode != written_word(r.mode) || back.task != written_word(r.task) ||
        back.component != written_word(r.component) || back.label != written_word(r.label) || back.tid != r.tid ||
        back.time_ns != r.time_ns || back.has_syscall != r.has_syscall || back.syscall != r.syscall ||
        back.has_signal != r.has_signal || back.signal != r.signal || back.frames != r.frames) {
      std::abort();
    }
  }
  if (fmt::ModuleLine m, back; fmt::parse(line, m)) {
    if (!rewritten(m, buf, back) || back.id != m.id || back.base != m.base || back.lo != m.lo || back.hi != m.hi ||
        back.build_id != m.build_id || back.path != m.path) {
      std::abort();
    }
  }
  if (fmt::FrameLine f, back; fmt::parse(line, f)) {
    if (!rewritten(f, buf, back) || back.index != f.index || back.pc != f.pc || back.module != f.module ||
        back.offset != f.offset) {
      std::abort();
    }
  }
  if (fmt::RepeatLine r, back; fmt::parse(line, r)) {
    if (!rewritten(r, buf, back) || back.first != r.first || back.count != r.count || back.total != r.total ||
        back.time_ns != r.time_ns) {
      std::abort();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const rack::backtrace::ReportFile f = rack::backtrace::parse_report_text(text, "fuzz.report");
  if (f.errors.size() > rack::backtrace::kMaxReportErrors + 1) std::abort();
  for (const auto& e : f.errors) {
    if (e.rfind("fuzz.report", 0) != 0) std::abort();
  }
  for (const auto& r : f.reports) {
    if (std::to_string(r.pcs.size()) != r.field("frames") && r.field("frames").find("0x") != 0) {
      // frames= may be written in any base strtoull reads; compare numerically then.
      if (std::strtoull(r.field("frames").c_str(), nullptr, 0) != r.pcs.size()) std::abort();
    }
  }
  for (const auto& r : f.reports) (void)f.module_of(r.pcs.empty() ? 0 : r.pcs[0]);
  for (std::size_t at = 0; at < text.size();) {
    const std::size_t nl = text.find('\n', at);
    const std::size_t end = nl == std::string::npos ? text.size() : nl;
    round_trip(std::string_view(text).substr(at, end - at));
    at = end + 1;
  }
  return 0;
}
