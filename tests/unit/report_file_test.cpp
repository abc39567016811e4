// Mode-switch report files (tools/backtrace/report_file.h) from hostile sources: a
// FIFO, a device, a directory, a file over the limit, garbage, a flood of bad lines.
// Each is refused or read with errors that name the file and the line; none hangs.
#include "report_file.h"

#include <gtest/gtest.h>

#include <string>

#include "hostile_files.h"

namespace rack::backtrace {
namespace {

using test::HangGuard;
using test::HostileDir;

constexpr char kGood[] =
    "RACK-MODESWITCH-REPORT 1 program=rackd pid=1\n"
    "module 0 base=0x1000 lo=0x1000 hi=0x2000 build_id=- path=/usr/bin/rackd\n"
    "report 1 reason=SYSCALL mode=warn task=t frames=1\n"
    "frame 0 0x1234\n"
    "end 1\n";

TEST(ReportFileTest, AGoodFileLoads) {
  HostileDir d("report");
  const ReportFile f = load_report_file(d.write("good.report", kGood));
  EXPECT_TRUE(f.errors.empty());
  ASSERT_EQ(f.reports.size(), 1u);
  EXPECT_EQ(f.reports[0].pcs.size(), 1u);
}

TEST(ReportFileTest, FifoDeviceDirectoryAndHugeFilesAreRefusedWithTheirName) {
  HostileDir d("report");
  const std::string fifo = d.fifo("pipe.report");
  HangGuard guard("load_report_file on a FIFO");
  struct Case {
    std::string path;
    std::string words;
  };
  const Case cases[] = {
      {fifo, "the report file is a FIFO, not a regular file"},
      {"/dev/zero", "the report file is a character device"},
      {d.subdir("dir.report"), "the report file is a directory"},
      {d.sparse("huge.report", kMaxReportFileBytes + 1), "more than the limit of 64 MiB"},
      {d.path("absent.report"), "cannot open the report file: No such file or directory"},
  };
  for (const auto& c : cases) {
    const ReportFile f = load_report_file(c.path);
    EXPECT_TRUE(f.unreadable) << c.path;
    EXPECT_TRUE(f.reports.empty());
    ASSERT_EQ(f.errors.size(), 1u) << c.path;
    EXPECT_EQ(f.errors[0].rfind(c.path + ": ", 0), 0u) << f.errors[0];
    EXPECT_NE(f.errors[0].find(c.words), std::string::npos) << f.errors[0];
  }
}

TEST(ReportFileTest, GarbageAndTruncationNameTheLine) {
  const ReportFile bin = parse_report_text(std::string("\x7f"
                                                       "ELF\x02\x01\x01\0\0\0",
                                                       10),
                                           "x.report");
  ASSERT_EQ(bin.errors.size(), 1u);
  EXPECT_NE(bin.errors[0].find("x.report:1: not a RACK mode-switch report"), std::string::npos) << bin.errors[0];
  const std::string cut = std::string(kGood).substr(0, std::string(kGood).find("frame 0"));
  const ReportFile t = parse_report_text(cut, "cut.report");
  ASSERT_EQ(t.errors.size(), 1u);
  EXPECT_NE(t.errors[0].find("cut.report:3: report 1 is truncated"), std::string::npos) << t.errors[0];
  const ReportFile n = parse_report_text(std::string(kGood) + "frame 99999999999999999999999 0x1\n", "n.report");
  ASSERT_FALSE(n.errors.empty());
  EXPECT_NE(n.errors[0].find("n.report:6:"), std::string::npos) << n.errors[0];
}

TEST(ReportFileTest, AFloodOfBadLinesKeepsAShortList) {
  std::string text = "RACK-MODESWITCH-REPORT 1 program=x\n";
  for (int i = 0; i < 5000; ++i) text += "garbage line\n";
  const ReportFile f = parse_report_text(text, "flood.report");
  ASSERT_EQ(f.errors.size(), kMaxReportErrors + 1);
  EXPECT_NE(f.errors[0].find("flood.report:2: unknown line"), std::string::npos) << f.errors[0];
  EXPECT_EQ(f.errors.back(), "flood.report: " + std::to_string(5000 - kMaxReportErrors) + " more errors not listed");
}

}  // namespace
}  // namespace rack::backtrace
