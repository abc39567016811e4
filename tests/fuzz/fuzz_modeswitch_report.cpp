// libFuzzer harness: mode-switch report files (rack::backtrace::parse_report_text, what
// rack-backtrace reads). Invariants: every complete report has exactly the frames its
// header announced; the error list stays within its limit; errors name the file.
//
// Build: clang++-14 -std=c++20 -g -O1 -fsanitize=fuzzer,address,undefined this file with
//   tools/backtrace/report_file.cpp core/rt/src/input_file.cpp; -Itools/backtrace -Icore/rt/include.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "report_file.h"

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
  return 0;
}
