#include "rack/rt/modeswitch_report.h"

#include <cerrno>
#include <cstdlib>

#include "signal_text.h"

namespace rack::rt::modeswitch::report {

namespace {

// `line` begins with `word` and a space: the rest after them, else false.
bool after_word(std::string_view line, std::string_view word, std::string_view& rest) noexcept {
  if (line.size() <= word.size() || line.substr(0, word.size()) != word || line[word.size()] != ' ') return false;
  rest = line.substr(word.size() + 1);
  return true;
}

// The first word of `text` (after white space), and what follows it.
std::string_view first_word(std::string_view text, std::string_view* rest = nullptr) noexcept {
  std::size_t i = 0;
  while (i < text.size() && is_field_space(text[i])) ++i;
  std::size_t j = i;
  while (j < text.size() && !is_field_space(text[j])) ++j;
  if (rest != nullptr) *rest = text.substr(j);
  return text.substr(i, j - i);
}

bool parse_signed(std::string_view text, int64_t& out) noexcept {
  const bool negative = !text.empty() && text.front() == '-';
  uint64_t v = 0;
  if (!parse_number(negative ? text.substr(1) : text, v)) return false;
  if (negative ? v > uint64_t{1} << 63 : v > static_cast<uint64_t>(INT64_MAX)) return false;
  out = negative ? static_cast<int64_t>(0 - v) : static_cast<int64_t>(v);
  return true;
}

// A word field: kNone for an empty value (values are single words).
std::string_view word_or_none(std::string_view v) noexcept { return v.empty() ? kNone : v; }

}  // namespace

LineKind line_kind(std::string_view line) noexcept {
  std::string_view rest;
  if (after_word(line, kMagic, rest)) return LineKind::kHeader;
  if (after_word(line, kModuleWord, rest)) return LineKind::kModule;
  if (after_word(line, kReportWord, rest)) return LineKind::kReport;
  if (after_word(line, kDetailWord, rest)) return LineKind::kDetail;
  if (after_word(line, kFrameWord, rest)) return LineKind::kFrame;
  if (after_word(line, kEndWord, rest)) return LineKind::kEnd;
  if (after_word(line, kRepeatWord, rest)) return LineKind::kRepeat;
  return LineKind::kOther;
}

bool parse_number(std::string_view text, uint64_t& out) noexcept {
  // strtoull wants a terminated string: numbers are short, longer text is no number.
  char buf[80];
  if (text.empty() || text.size() >= sizeof buf) return false;
  for (std::size_t k = 0; k < text.size(); ++k) buf[k] = text[k];
  buf[text.size()] = '\0';
  char* end = nullptr;
  errno = 0;
  out = std::strtoull(buf, &end, 0);
  return errno == 0 && end != nullptr && *end == '\0';
}

// ---------------------------------------------------------------- writers

std::size_t format(const HeaderLine& l, char* buf, std::size_t cap) noexcept {
  Text t(buf, cap);
  t.s(kMagic).c(' ').u(l.version);
  t.s(" program=").s(word_or_none(l.program)).s(" pid=").i(l.pid).s(" start_ns=").i(l.start_ns);
  t.s(" exe=").s(l.exe).c('\n');
  return t.size();
}

std::size_t format(const ModuleLine& l, char* buf, std::size_t cap) noexcept {
  Text t(buf, cap);
  t.s(kModuleWord).c(' ').i(l.id).s(" base=").hex(l.base).s(" lo=").hex(l.lo).s(" hi=").hex(l.hi);
  t.s(" build_id=").s(word_or_none(l.build_id)).s(" path=").s(l.path).c('\n');
  return t.size();
}

std::size_t format(const ReportLine& l, char* buf, std::size_t cap) noexcept {
  Text t(buf, cap);
  t.s(kReportWord).c(' ').u(l.sequence).s(" reason=").s(word_or_none(l.reason)).s(" mode=").s(word_or_none(l.mode));
  t.s(" task=").s(word_or_none(l.task));
  t.s(" component=").s(word_or_none(l.component));
  t.s(" label=").s(word_or_none(l.label));
  t.s(" tid=").i(l.tid).s(" time_ns=").i(l.time_ns);
  if (l.has_syscall) t.s(" syscall=").i(l.syscall);
  if (l.has_signal) t.s(" signal=").i(l.signal);
  t.s(" frames=").u(l.frames).c('\n');
  return t.size();
}

std::size_t format_detail_start(char* buf, std::size_t cap) noexcept {
  Text t(buf, cap);
  t.s(kDetailWord).c(' ');
  return t.size();
}

std::size_t format(const FrameLine& l, char* buf, std::size_t cap) noexcept {
  Text t(buf, cap);
  t.s(kFrameWord).c(' ').u(l.index).c(' ').hex(l.pc, 12);
  if (!l.module.empty()) t.c(' ').s(l.module).c('+').hex(l.offset);
  t.c('\n');
  return t.size();
}

std::size_t format_end(uint64_t sequence, char* buf, std::size_t cap) noexcept {
  Text t(buf, cap);
  t.s(kEndWord).c(' ').u(sequence).c('\n');
  return t.size();
}

std::size_t format(const RepeatLine& l, char* buf, std::size_t cap) noexcept {
  Text t(buf, cap);
  t.s(kRepeatWord).c(' ').u(l.first).s(" count=").u(l.count).s(" total=").u(l.total).s(" time_ns=").i(l.time_ns);
  t.c('\n');
  return t.size();
}

// ---------------------------------------------------------------- readers

bool parse(std::string_view line, HeaderLine& out) noexcept {
  std::string_view rest;
  if (!after_word(line, kMagic, rest)) return false;
  out = HeaderLine{};
  std::string_view fields;
  if (!parse_number(first_word(rest, &fields), out.version)) return false;
  const auto exe_at = fields.find(" exe=");
  if (exe_at != std::string_view::npos) out.exe = fields.substr(exe_at + 5);
  bool ok = true;
  for_each_field(fields.substr(0, exe_at), [&](std::string_view key, std::string_view value) {
    if (key == "program") out.program = value;
    else if (key == "pid") ok = parse_signed(value, out.pid) && ok;
    else if (key == "start_ns") ok = parse_signed(value, out.start_ns) && ok;
  });
  return ok;
}

bool parse(std::string_view line, ModuleLine& out) noexcept {
  std::string_view rest;
  if (!after_word(line, kModuleWord, rest)) return false;
  out = ModuleLine{};
  const auto path_at = rest.find(" path=");
  if (path_at == std::string_view::npos) return false;
  std::string_view fields;
  if (!parse_signed(first_word(rest.substr(0, path_at), &fields), out.id)) return false;
  bool base = false, lo = false, hi = false, ok = true;
  for_each_field(fields, [&](std::string_view key, std::string_view value) {
    if (key == "base") ok = (base = parse_number(value, out.base)) && ok;
    else if (key == "lo") ok = (lo = parse_number(value, out.lo)) && ok;
    else if (key == "hi") ok = (hi = parse_number(value, out.hi)) && ok;
    else if (key == "build_id") out.build_id = value == kNone ? std::string_view() : value;
  });
  out.path = rest.substr(path_at + 6);
  return ok && base && lo && hi;
}

bool parse(std::string_view line, ReportLine& out) noexcept {
  std::string_view rest;
  if (!after_word(line, kReportWord, rest)) return false;
  out = ReportLine{};
  std::string_view fields;
  if (!parse_number(first_word(rest, &fields), out.sequence)) return false;
  bool reason = false, frames = false, ok = true;
  for_each_field(fields, [&](std::string_view key, std::string_view value) {
    if (key == "reason") {
      out.reason = value;
      reason = true;
    } else if (key == "mode") {
      out.mode = value;
    } else if (key == "task") {
      out.task = value;
    } else if (key == "component") {
      out.component = value;
    } else if (key == "label") {
      out.label = value;
    } else if (key == "tid") {
      ok = parse_signed(value, out.tid) && ok;
    } else if (key == "time_ns") {
      ok = parse_signed(value, out.time_ns) && ok;
    } else if (key == "syscall") {
      ok = (out.has_syscall = parse_signed(value, out.syscall)) && ok;
    } else if (key == "signal") {
      ok = (out.has_signal = parse_signed(value, out.signal)) && ok;
    } else if (key == "frames") {
      ok = (frames = parse_number(value, out.frames)) && ok;
    }
  });
  return ok && reason && frames;
}

bool parse_detail(std::string_view line, std::string_view& text) noexcept {
  return after_word(line, kDetailWord, text);
}

bool parse(std::string_view line, FrameLine& out) noexcept {
  std::string_view rest;
  if (!after_word(line, kFrameWord, rest)) return false;
  out = FrameLine{};
  std::string_view after_index, after_pc;
  if (!parse_number(first_word(rest, &after_index), out.index)) return false;
  if (!parse_number(first_word(after_index, &after_pc), out.pc)) return false;
  // Optional: where, for a reader without the binaries ("libc.so.6+0xf838f").
  const std::string_view where = first_word(after_pc);
  if (const auto plus = where.rfind('+'); plus != std::string_view::npos && plus > 0) {
    uint64_t offset = 0;
    if (parse_number(where.substr(plus + 1), offset)) {
      out.module = where.substr(0, plus);
      out.offset = offset;
    }
  }
  return true;
}

bool parse_end(std::string_view line, uint64_t& sequence) noexcept {
  std::string_view rest;
  return after_word(line, kEndWord, rest) && parse_number(rest, sequence);
}

bool parse(std::string_view line, RepeatLine& out) noexcept {
  std::string_view rest;
  if (!after_word(line, kRepeatWord, rest)) return false;
  out = RepeatLine{};
  std::string_view fields;
  if (!parse_number(first_word(rest, &fields), out.first)) return false;
  bool count = false, ok = true;
  for_each_field(fields, [&](std::string_view key, std::string_view value) {
    if (key == "count") ok = (count = parse_number(value, out.count)) && ok;
    else if (key == "total") ok = parse_number(value, out.total) && ok;
    else if (key == "time_ns") ok = parse_signed(value, out.time_ns) && ok;
  });
  return ok && count;
}

}  // namespace rack::rt::modeswitch::report
