// The mode-switch report file format, version 1: the one definition that its writer
// (rack::rt::modeswitch, rack/rt/modeswitch.h) and its readers (rack-backtrace's parser,
// tools/backtrace/report_file.h, which rack-gui's report view runs too) share.
// tools/backtrace/README.md describes the format for users.
//
// Each kind of line has a struct, a writer (format) and a reader (parse) here, so a
// change of the format is a change of this file and its .cpp; the unit test
// ModeswitchReportFormatTest writes every field of every kind of line and reads it back.
//
//   RACK-MODESWITCH-REPORT 1 program=rackd pid=4242 start_ns=... exe=/usr/bin/rackd
//   module 0 base=0x... lo=0x... hi=0x... build_id=76acf9... path=/usr/bin/rackd
//   report 1 reason=SYSCALL mode=warn task=demo:cmd component=demo label=... tid=4245 time_ns=... syscall=1 frames=9
//   detail write(0x4, ...): fd 4 is not a registered RT device
//   frame 0 0x7f26cbe3638f libc.so.6+0xf838f
//   end 1
//   repeat 1 count=12 total=13 time_ns=...
//
// Values are single words (no spaces), except the header's exe, the module's path and
// the detail text, which run to the end of their line.
//
// Real-time contract: the format() writers are async-signal-safe and RT-safe (no
// allocation, lock or system call): they write into the caller's buffer, a line that does
// not fit is cut. The parse() readers do not allocate (their string_views point into the
// line) and never throw, but they are meant for tools. Thread-safety: reentrant.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace rack::rt::modeswitch::report {

inline constexpr std::string_view kMagic = "RACK-MODESWITCH-REPORT";
inline constexpr uint64_t kVersion = 1;

// The word that begins each line after the header (a space follows it).
inline constexpr std::string_view kModuleWord = "module";
inline constexpr std::string_view kReportWord = "report";
inline constexpr std::string_view kDetailWord = "detail";
inline constexpr std::string_view kFrameWord = "frame";
inline constexpr std::string_view kEndWord = "end";
inline constexpr std::string_view kRepeatWord = "repeat";

// A word field without a value (a report outside any component: component=-).
inline constexpr std::string_view kNone = "-";

enum class LineKind : uint8_t { kHeader, kModule, kReport, kDetail, kFrame, kEnd, kRepeat, kOther };
// By the line's first word (the header by kMagic).
[[nodiscard]] LineKind line_kind(std::string_view line) noexcept;

// The first line. `version` other than kVersion: a file this definition does not read.
struct HeaderLine {
  uint64_t version = kVersion;
  std::string_view program;
  int64_t pid = 0;
  int64_t start_ns = 0;  // CLOCK_REALTIME
  std::string_view exe;  // to the end of the line
};

// One loaded object with executable code (before the first report that needs it).
struct ModuleLine {
  int64_t id = 0;
  uint64_t base = 0;          // load bias (dl_iterate_phdr's dlpi_addr)
  uint64_t lo = 0, hi = 0;    // executable range, absolute
  std::string_view build_id;  // GNU build id in hex; written as kNone when empty
  std::string_view path;      // to the end of the line
};

// The first line of a report: `frames` frame lines and an end line follow it.
struct ReportLine {
  uint64_t sequence = 0;
  std::string_view reason;     // rack::rt::modeswitch::reason_name()
  std::string_view mode;       // mode_name()
  std::string_view task;       // kNone when empty (written), "" when absent (read)
  std::string_view component;  // likewise
  std::string_view label;      // the component's TiMS address; likewise
  int64_t tid = 0;             // kernel thread id
  int64_t time_ns = 0;         // CLOCK_REALTIME
  bool has_syscall = false;    // SYSCALL reports: the system call's number
  int64_t syscall = 0;
  bool has_signal = false;  // CRASH reports: the signal's number
  int64_t signal = 0;
  uint64_t frames = 0;
};

// One call site, innermost first; `module` (the file name of the object holding `pc`)
// and `offset` (pc minus its load bias) are written when module is not empty.
struct FrameLine {
  uint64_t index = 0;
  uint64_t pc = 0;
  std::string_view module;
  uint64_t offset = 0;
};

// `count` more reports identical to report `first` since the last line about it;
// `total` counts them all, report `first` included.
struct RepeatLine {
  uint64_t first = 0;
  uint64_t count = 0;
  uint64_t total = 0;
  int64_t time_ns = 0;  // CLOCK_REALTIME
};

// Writers: one whole line with its '\n' into buf (at most cap - 1 bytes; a longer line
// is cut). Return the bytes written. The detail line's text is written by the caller
// after format_detail_start() ("detail "), then '\n'.
std::size_t format(const HeaderLine& l, char* buf, std::size_t cap) noexcept;
std::size_t format(const ModuleLine& l, char* buf, std::size_t cap) noexcept;
std::size_t format(const ReportLine& l, char* buf, std::size_t cap) noexcept;
std::size_t format_detail_start(char* buf, std::size_t cap) noexcept;
std::size_t format(const FrameLine& l, char* buf, std::size_t cap) noexcept;
std::size_t format_end(uint64_t sequence, char* buf, std::size_t cap) noexcept;
std::size_t format(const RepeatLine& l, char* buf, std::size_t cap) noexcept;

// Readers of one line (without its '\n'). False: the line is not of that kind or a
// field is missing or malformed. Numbers are read as strtoull(..., 0) does (decimal,
// 0x hex); a field given twice counts with its last value; other key=value words are
// passed over (a newer writer may add fields).
// The header: version and its word fields; a version other than kVersion reads as true
// with that version (the caller refuses it), so only the magic and a number are needed.
[[nodiscard]] bool parse(std::string_view line, HeaderLine& out) noexcept;
[[nodiscard]] bool parse(std::string_view line, ModuleLine& out) noexcept;  // id, base, lo, hi, path
[[nodiscard]] bool parse(std::string_view line, ReportLine& out) noexcept;  // sequence, reason, frames
[[nodiscard]] bool parse_detail(std::string_view line, std::string_view& text) noexcept;
[[nodiscard]] bool parse(std::string_view line, FrameLine& out) noexcept;  // index, pc
[[nodiscard]] bool parse_end(std::string_view line, uint64_t& sequence) noexcept;
[[nodiscard]] bool parse(std::string_view line, RepeatLine& out) noexcept;  // first, count

// White space between words (what std::isspace says in the C locale).
[[nodiscard]] constexpr bool is_field_space(char c) noexcept {
  return c == ' ' || c == '\t' || c == '\n' || c == '\v' || c == '\f' || c == '\r';
}

// The key=value words of `fields` (a line after its first word), in order; a word without
// '=' is passed to nobody. Fn: void(std::string_view key, std::string_view value).
template <typename Fn>
void for_each_field(std::string_view fields, Fn fn) {
  std::size_t i = 0;
  while (i < fields.size()) {
    while (i < fields.size() && is_field_space(fields[i])) ++i;
    std::size_t j = i;
    while (j < fields.size() && !is_field_space(fields[j])) ++j;
    const std::string_view word = fields.substr(i, j - i);
    if (const auto eq = word.find('='); eq != std::string_view::npos) fn(word.substr(0, eq), word.substr(eq + 1));
    i = j;
  }
}

// A number as strtoull(text, &end, 0) reads it (decimal, 0x hex, 0 octal), the whole of
// `text`; false when empty, not a number or out of range.
[[nodiscard]] bool parse_number(std::string_view text, uint64_t& out) noexcept;

}  // namespace rack::rt::modeswitch::report
