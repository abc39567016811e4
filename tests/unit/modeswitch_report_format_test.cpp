// The mode-switch report format (rack/rt/modeswitch_report.h) from writer to reader:
// every field of every kind of line written by the writer's format() and read back by
// its parse(), and whole files written line by line and read by rack-backtrace's parser
// (tools/backtrace/report_file.h), repeat lines included.
#include "rack/rt/modeswitch_report.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <string>

#include "report_file.h"

namespace rack::rt::modeswitch::report {
namespace {

template <typename Line>
std::string written(const Line& l) {
  char buf[1024];
  return std::string(buf, format(l, buf, sizeof buf));
}

std::string end_line(uint64_t sequence) {
  char buf[64];
  return std::string(buf, format_end(sequence, buf, sizeof buf));
}

std::string detail_line(const std::string& text) {
  char buf[64];
  return std::string(buf, format_detail_start(buf, sizeof buf)) + text + "\n";
}

// The line without its '\n' (what a reader gets from getline).
std::string_view body(const std::string& line) {
  EXPECT_FALSE(line.empty());
  EXPECT_EQ(line.back(), '\n');
  return std::string_view(line).substr(0, line.size() - 1);
}

ReportLine full_report(uint64_t sequence, uint64_t frames) {
  ReportLine l;
  l.sequence = sequence;
  l.reason = "SYSCALL";
  l.mode = "warn";
  l.task = "demo:cmd";
  l.component = "demo";
  l.label = "ModeSwitchDemo(0/0)";
  l.tid = 4245;
  l.time_ns = 1'764'000'000'123'456'789;
  l.has_syscall = true;
  l.syscall = 1;
  l.frames = frames;
  return l;
}

TEST(ModeswitchReportFormatTest, TheHeaderKeepsEveryField) {
  HeaderLine h;
  h.program = "rackd";
  h.pid = 4242;
  h.start_ns = 1'764'000'000'000'000'001;
  h.exe = "/opt/rack rt/bin/rackd";  // a path may hold spaces: it runs to the end
  const std::string line = written(h);
  EXPECT_EQ(line.rfind(std::string(kMagic) + " 1 ", 0), 0u) << line;
  EXPECT_EQ(line_kind(body(line)), LineKind::kHeader);
  HeaderLine back;
  ASSERT_TRUE(parse(body(line), back)) << line;
  EXPECT_EQ(back.version, kVersion);
  EXPECT_EQ(back.program, "rackd");
  EXPECT_EQ(back.pid, 4242);
  EXPECT_EQ(back.start_ns, h.start_ns);
  EXPECT_EQ(back.exe, h.exe);
}

TEST(ModeswitchReportFormatTest, AModuleKeepsEveryFieldAndNoBuildIdReadsEmpty) {
  ModuleLine m;
  m.id = 5;
  m.base = 0x7f5b9d33e000;
  m.lo = 0x7f5b9d364000;
  m.hi = 0x7f5b9d4b9000;
  m.build_id = "93ac61aa0b";
  m.path = "/lib/x86_64-linux-gnu/libc.so.6";
  const std::string line = written(m);
  EXPECT_EQ(line_kind(body(line)), LineKind::kModule);
  ModuleLine back;
  ASSERT_TRUE(parse(body(line), back)) << line;
  EXPECT_EQ(back.id, 5);
  EXPECT_EQ(back.base, m.base);
  EXPECT_EQ(back.lo, m.lo);
  EXPECT_EQ(back.hi, m.hi);
  EXPECT_EQ(back.build_id, m.build_id);
  EXPECT_EQ(back.path, m.path);

  m.build_id = "";
  const std::string none = written(m);
  EXPECT_NE(none.find(" build_id=- "), std::string::npos) << none;
  ASSERT_TRUE(parse(body(none), back));
  EXPECT_EQ(back.build_id, "");
}

TEST(ModeswitchReportFormatTest, AReportLineKeepsEveryField) {
  ReportLine r = full_report(17, 9);
  r.has_signal = true;  // both optional fields at once: each is read on its own
  r.signal = 11;
  const std::string line = written(r);
  EXPECT_EQ(line_kind(body(line)), LineKind::kReport);
  ReportLine back;
  ASSERT_TRUE(parse(body(line), back)) << line;
  EXPECT_EQ(back.sequence, 17u);
  EXPECT_EQ(back.reason, "SYSCALL");
  EXPECT_EQ(back.mode, "warn");
  EXPECT_EQ(back.task, "demo:cmd");
  EXPECT_EQ(back.component, "demo");
  EXPECT_EQ(back.label, "ModeSwitchDemo(0/0)");
  EXPECT_EQ(back.tid, 4245);
  EXPECT_EQ(back.time_ns, r.time_ns);
  EXPECT_TRUE(back.has_syscall);
  EXPECT_EQ(back.syscall, 1);
  EXPECT_TRUE(back.has_signal);
  EXPECT_EQ(back.signal, 11);
  EXPECT_EQ(back.frames, 9u);

  // Optional fields left out stay out; empty words are written as kNone.
  ReportLine bare;
  bare.sequence = 2;
  bare.reason = "NOMLOCK";
  bare.mode = "warn";
  bare.tid = -1;
  bare.time_ns = -5;
  const std::string bare_line = written(bare);
  EXPECT_NE(bare_line.find(" task=- component=- label=- "), std::string::npos) << bare_line;
  ASSERT_TRUE(parse(body(bare_line), back)) << bare_line;
  EXPECT_FALSE(back.has_syscall);
  EXPECT_FALSE(back.has_signal);
  EXPECT_EQ(back.task, kNone);
  EXPECT_EQ(back.tid, -1);
  EXPECT_EQ(back.time_ns, -5);
  EXPECT_EQ(back.frames, 0u);
}

TEST(ModeswitchReportFormatTest, DetailFrameAndEndLinesKeepTheirFields) {
  const std::string detail = detail_line("write(0x4, 0x55777a6f7b08, ...): fd 4 is not a registered RT device");
  std::string_view text;
  ASSERT_TRUE(parse_detail(body(detail), text));
  EXPECT_EQ(text, "write(0x4, 0x55777a6f7b08, ...): fd 4 is not a registered RT device");

  FrameLine f;
  f.index = 3;
  f.pc = 0x7f26cbe3638f;
  f.module = "libc.so.6";
  f.offset = 0xf838f;
  const std::string frame = written(f);
  EXPECT_EQ(frame, "frame 3 0x7f26cbe3638f libc.so.6+0xf838f\n");
  FrameLine back;
  ASSERT_TRUE(parse(body(frame), back));
  EXPECT_EQ(back.index, 3u);
  EXPECT_EQ(back.pc, f.pc);
  EXPECT_EQ(back.module, "libc.so.6");
  EXPECT_EQ(back.offset, 0xf838fu);

  f.module = "";  // a PC outside every module: no where
  f.pc = 0x1234;
  const std::string bare = written(f);
  EXPECT_EQ(bare, "frame 3 0x000000001234\n");  // call sites are written 12 digits wide
  ASSERT_TRUE(parse(body(bare), back));
  EXPECT_EQ(back.pc, 0x1234u);
  EXPECT_EQ(back.module, "");

  uint64_t sequence = 0;
  ASSERT_TRUE(parse_end(body(end_line(UINT64_MAX)), sequence));
  EXPECT_EQ(sequence, UINT64_MAX);
}

TEST(ModeswitchReportFormatTest, ARepeatLineKeepsEveryField) {
  const RepeatLine r{7, 12, 13, 1'764'000'000'999'000'000};
  const std::string line = written(r);
  EXPECT_EQ(line_kind(body(line)), LineKind::kRepeat);
  RepeatLine back;
  ASSERT_TRUE(parse(body(line), back)) << line;
  EXPECT_EQ(back.first, 7u);
  EXPECT_EQ(back.count, 12u);
  EXPECT_EQ(back.total, 13u);
  EXPECT_EQ(back.time_ns, r.time_ns);
}

TEST(ModeswitchReportFormatTest, AWrittenFileReadsBackWithItsRepeatsAggregated) {
  HeaderLine h;
  h.program = "rackd";
  h.pid = 77;
  h.exe = "/usr/bin/rackd";
  ModuleLine m;
  m.id = 0;
  m.base = 0x55d0c0000000;
  m.lo = 0x55d0c000d000;
  m.hi = 0x55d0c0062000;
  m.build_id = "76acf9";
  m.path = "/usr/bin/rackd";
  std::string file = written(h) + written(m);
  // Report 1 with two frames, report 2 with one; report 1 repeats 3 + 4 times
  // (two repeat lines: their counts add up), report 2 once.
  file += written(full_report(1, 2)) + detail_line("first detail");
  file += written(FrameLine{0, 0x55d0c0010000, "rackd", 0x10000}) + written(FrameLine{1, 0x55d0c0020000, "", 0});
  file += end_line(1);
  file += written(RepeatLine{1, 3, 4, 10});
  ReportLine second = full_report(2, 1);
  second.reason = "CRASH";
  second.has_syscall = false;
  second.has_signal = true;
  second.signal = 11;
  second.component = "";
  file += written(second) + detail_line("SIGSEGV (si_code 1) at address 0x0");
  file += written(FrameLine{0, 0x55d0c0030000, "rackd", 0x30000}) + end_line(2);
  file += written(RepeatLine{1, 4, 8, 20}) + written(RepeatLine{2, 1, 2, 30});

  const backtrace::ReportFile f = backtrace::parse_report_text(file, "written.report");
  EXPECT_TRUE(f.errors.empty()) << f.errors.front();
  EXPECT_EQ(f.header, std::string(body(written(h))));
  ASSERT_EQ(f.modules.size(), 1u);
  EXPECT_EQ(f.modules[0].id, 0);
  EXPECT_EQ(f.modules[0].base, m.base);
  EXPECT_EQ(f.modules[0].lo, m.lo);
  EXPECT_EQ(f.modules[0].hi, m.hi);
  EXPECT_EQ(f.modules[0].build_id, "76acf9");
  EXPECT_EQ(f.modules[0].path, "/usr/bin/rackd");
  ASSERT_EQ(f.reports.size(), 2u);
  const backtrace::Report& r1 = f.reports[0];
  EXPECT_EQ(r1.sequence, 1u);
  EXPECT_EQ(r1.field("reason"), "SYSCALL");
  EXPECT_EQ(r1.field("mode"), "warn");
  EXPECT_EQ(r1.field("task"), "demo:cmd");
  EXPECT_EQ(r1.field("component"), "demo");
  EXPECT_EQ(r1.field("label"), "ModeSwitchDemo(0/0)");
  EXPECT_EQ(r1.field("tid"), "4245");
  EXPECT_EQ(r1.field("time_ns"), "1764000000123456789");
  EXPECT_EQ(r1.field("syscall"), "1");
  EXPECT_EQ(r1.field("signal"), "");
  EXPECT_EQ(r1.detail, "first detail");
  ASSERT_EQ(r1.pcs.size(), 2u);
  EXPECT_EQ(r1.pcs[0], 0x55d0c0010000u);
  EXPECT_EQ(r1.pcs[1], 0x55d0c0020000u);
  EXPECT_EQ(r1.repeats, 7u);  // 3 + 4: report 1 stands for 8
  EXPECT_EQ(r1.where, "written.report:3");
  const backtrace::Report& r2 = f.reports[1];
  EXPECT_EQ(r2.sequence, 2u);
  EXPECT_EQ(r2.field("reason"), "CRASH");
  EXPECT_EQ(r2.field("component"), "-");
  EXPECT_EQ(r2.field("signal"), "11");
  EXPECT_EQ(r2.field("syscall"), "");
  EXPECT_EQ(r2.detail, "SIGSEGV (si_code 1) at address 0x0");
  ASSERT_EQ(r2.pcs.size(), 1u);
  EXPECT_EQ(r2.repeats, 1u);
  EXPECT_EQ(f.module_of(r2.pcs[0]), &f.modules[0]);
}

TEST(ModeswitchReportFormatTest, ALineTooLongForTheBufferIsCutNotOverrun) {
  ModuleLine m;
  m.path = "/a/very/long/path/of/a/plugin/that/does/not/fit.so";
  char buf[24];
  std::memset(buf, 'X', sizeof buf);
  const std::size_t n = format(m, buf, 16);
  EXPECT_EQ(n, 15u);  // capacity less one, as the writer's other texts
  EXPECT_EQ(buf[16], 'X');
  EXPECT_EQ(std::string(buf, n), "module 0 base=0");
}

TEST(ModeswitchReportFormatTest, ReadersRefuseLinesOfAnotherKindOrWithoutTheirFields) {
  ReportLine r;
  EXPECT_FALSE(parse("report 1 mode=warn frames=1", r));         // no reason
  EXPECT_FALSE(parse("report 1 reason=SYSCALL", r));             // no frames
  EXPECT_FALSE(parse("report x reason=SYSCALL frames=1", r));    // no sequence
  EXPECT_FALSE(parse("report 1 reason=A frames=1 tid=abc", r));  // a number that is none
  EXPECT_FALSE(parse("frame 0 0x1", r));
  ModuleLine m;
  EXPECT_FALSE(parse("module 0 base=0x1 lo=0x1 hi=0x2", m));  // no path
  EXPECT_FALSE(parse("module 0 lo=0x1 hi=0x2 path=/x", m));   // no base
  RepeatLine rep;
  EXPECT_FALSE(parse("repeat 1 total=3", rep));  // no count
  FrameLine f;
  EXPECT_FALSE(parse("frame 0", f));
  uint64_t seq = 0;
  EXPECT_FALSE(parse_end("end", seq));
  EXPECT_FALSE(parse_end("end 1 2", seq));
  EXPECT_EQ(line_kind("frames 1"), LineKind::kOther);
  EXPECT_EQ(line_kind("RACK-MODESWITCH-REPORT"), LineKind::kOther);
}

}  // namespace
}  // namespace rack::rt::modeswitch::report
