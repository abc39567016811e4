// rack/rt/input_file.h: a path where a regular file is expected is opened without
// waiting on a FIFO, checked on what was opened, and read no further than its limit;
// a path where a device is expected must be one. Every refusal names the path, the
// file's role and what was found.
#include "rack/rt/input_file.h"

#include <gtest/gtest.h>

#include <string>

#include "hostile_files.h"
#include "rack/core/registry.h"

namespace rack::rt {
namespace {

using test::HangGuard;
using test::HostileDir;

void expect_words(const std::string& text, std::initializer_list<std::string> words) {
  for (const auto& w : words) EXPECT_NE(text.find(w), std::string::npos) << "'" << w << "' not in: " << text;
}

TEST(InputFileTest, ReadsARegularFileWhole) {
  HostileDir d("input");
  const std::string p = d.write("a.txt", "hello\nworld\n");
  std::string out, error;
  ASSERT_TRUE(read_regular_file(p, 100, "test file", out, error)) << error;
  EXPECT_EQ(out, "hello\nworld\n");
}

TEST(InputFileTest, AFifoIsRefusedWithoutWaiting) {
  HostileDir d("input");
  const std::string p = d.fifo("pipe");
  HangGuard guard("read_regular_file on a FIFO");
  std::string out, error;
  EXPECT_FALSE(read_regular_file(p, 100, "map image", out, error));
  expect_words(error, {p + ": ", "the map image is a FIFO, not a regular file"});
  EXPECT_FALSE(check_regular_file(p, 100, "plug-in", error));
  expect_words(error, {p + ": ", "the plug-in is a FIFO"});
}

TEST(InputFileTest, DevicesAndDirectoriesAreRefused) {
  std::string out, error;
  EXPECT_FALSE(read_regular_file("/dev/zero", 1 << 20, "map image", out, error));
  expect_words(error, {"/dev/zero: ", "is a character device, not a regular file"});
  EXPECT_TRUE(out.empty());
  HostileDir d("input");
  const std::string dir = d.subdir("folder");
  EXPECT_FALSE(read_regular_file(dir, 1 << 20, "log file", out, error));
  expect_words(error, {dir + ": ", "the log file is a directory"});
  EXPECT_FALSE(read_regular_file(d.path("missing"), 1 << 20, "log file", out, error));
  expect_words(error, {"missing: cannot open the log file: No such file or directory"});
  EXPECT_FALSE(read_regular_file("", 1 << 20, "log file", out, error));
  expect_words(error, {"no log file named"});
}

TEST(InputFileTest, AFileOverTheLimitIsRefusedBeforeItIsRead) {
  HostileDir d("input");
  const std::string p = d.sparse("big", uint64_t{5} << 30);  // 5 GiB, sparse
  std::string out, error;
  EXPECT_FALSE(read_regular_file(p, 1 << 20, "PCD file", out, error));
  expect_words(error, {p + ": the PCD file has 5 GiB, more than the limit of 1 MiB"});
  EXPECT_TRUE(out.empty());
  EXPECT_FALSE(check_regular_file(p, 1 << 20, "plug-in", error));
  expect_words(error, {"more than the limit of 1 MiB"});
}

TEST(InputFileTest, AFileWhoseSizeSaysNothingStopsAtTheLimit) {
  // /proc files report size 0: the limit holds while reading.
  std::string out, error;
  ASSERT_TRUE(read_regular_file("/proc/self/status", 1 << 20, "status", out, error)) << error;
  EXPECT_NE(out.find("Name:"), std::string::npos);
  EXPECT_FALSE(read_regular_file("/proc/self/status", 16, "status", out, error));
  expect_words(error, {"/proc/self/status: byte 16: the status grew past the limit of 16 B"});
  EXPECT_TRUE(out.empty());
}

TEST(InputFileTest, StreamsInPiecesWithOffsets) {
  HostileDir d("input");
  const std::string p = d.write("r", "0123456789");
  InputFile f;
  std::string error;
  ASSERT_TRUE(f.open(p, 10, "record file", error)) << error;
  EXPECT_EQ(f.size(), 10u);
  char buf[4];
  EXPECT_EQ(f.read(buf, 4, error), 4);
  EXPECT_EQ(f.offset(), 4u);
  EXPECT_EQ(f.remaining(), 6u);
  std::string rest;
  ASSERT_TRUE(f.read_all(rest, error)) << error;
  EXPECT_EQ(rest, "456789");
  EXPECT_EQ(f.read(buf, 4, error), 0);  // the end
  InputFile moved(std::move(f));
  EXPECT_TRUE(moved.is_open());
  EXPECT_FALSE(f.is_open());  // NOLINT(bugprone-use-after-move): moved-from state is defined
}

TEST(InputFileTest, DevicePathsMustBeCharacterDevices) {
  std::string error;
  EXPECT_TRUE(check_char_device("/dev/null", "serial port", error)) << error;
  HostileDir d("input");
  const std::string file = d.write("ttyFAKE", "not a tty");
  EXPECT_FALSE(check_char_device(file, "serial port", error));
  expect_words(error, {file + ": the serial port is a regular file, not a character device"});
  const std::string fifo = d.fifo("js0");
  EXPECT_FALSE(check_char_device(fifo, "joystick", error));
  expect_words(error, {"the joystick is a FIFO, not a character device"});
  EXPECT_FALSE(check_socket(file, "CAN bus socket", error));
  expect_words(error, {"the CAN bus socket is a regular file, not a socket"});
}

TEST(InputFileTest, APluginPathThatIsAFifoIsRefusedWithoutWaiting) {
  HostileDir d("input");
  const std::string fifo = d.fifo("plugin.so");
  HangGuard guard("dlopen of a FIFO");
  ComponentRegistry registry;
  try {
    registry.load_plugin(fifo);
    FAIL() << "a FIFO loaded as a plug-in";
  } catch (const std::runtime_error& e) {
    expect_words(e.what(), {fifo + ": the plug-in is a FIFO, not a regular file"});
  }
  try {
    registry.load_plugin("/dev/zero");
    FAIL() << "/dev/zero loaded as a plug-in";
  } catch (const std::runtime_error& e) {
    expect_words(e.what(), {"/dev/zero: the plug-in is a character device"});
  }
}

}  // namespace
}  // namespace rack::rt
