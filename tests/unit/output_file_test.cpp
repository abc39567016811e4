// rack/rt/output_file.h: a file that a later run will trust is written whole or not at
// all. The target is refused when it is a FIFO, a directory or a device (without
// waiting); the bytes reach it only at commit(); a failed write (a file size limit
// here, as a full disk would) leaves neither the target nor a temporary file.
#include "rack/rt/output_file.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "hostile_files.h"

namespace rack::rt {
namespace {

using test::HangGuard;
using test::HostileDir;

std::vector<std::string> entries(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) out.push_back(e.path().filename().string());
  return out;
}
std::string contents(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}
void expect_words(const std::string& text, std::initializer_list<std::string> words) {
  for (const auto& w : words) EXPECT_NE(text.find(w), std::string::npos) << "'" << w << "' not in: " << text;
}

TEST(OutputFileTest, TheTargetAppearsWholeAtCommitAndNotBefore) {
  HostileDir d("output");
  const std::string p = d.path("trace.json");
  OutputFile f;
  std::string error;
  ASSERT_TRUE(f.open(p, "trace", OutputMode::kReplace, error)) << error;
  ASSERT_TRUE(f.write("{\"a\":", error)) << error;
  EXPECT_FALSE(std::filesystem::exists(p)) << "a part of the file is visible before commit()";
  ASSERT_TRUE(f.write("1}", error)) << error;
  ASSERT_TRUE(f.commit(error)) << error;
  EXPECT_EQ(contents(p), "{\"a\":1}");
  EXPECT_EQ(entries(d.dir()), std::vector<std::string>{"trace.json"}) << "a temporary file was left";
  EXPECT_EQ(f.written(), 7u);
}

TEST(OutputFileTest, AnExistingFileIsReplacedOnlyAtCommitAndKeptWhenNotCommitted) {
  HostileDir d("output");
  const std::string p = d.write("graph.dot", "old");
  std::string error;
  {
    OutputFile f;
    ASSERT_TRUE(f.open(p, "graph", OutputMode::kReplace, error)) << error;
    ASSERT_TRUE(f.write("new, but never committed", error));
  }  // destroyed without commit(): discarded
  EXPECT_EQ(contents(p), "old");
  EXPECT_EQ(entries(d.dir()), std::vector<std::string>{"graph.dot"});
  OutputFile f;
  ASSERT_TRUE(f.open(p, "graph", OutputMode::kReplace, error)) << error;
  ASSERT_TRUE(f.write("new", error));
  EXPECT_EQ(contents(p), "old");
  ASSERT_TRUE(f.commit(error)) << error;
  EXPECT_EQ(contents(p), "new");
}

TEST(OutputFileTest, FifosDirectoriesAndDevicesAreRefusedWithoutWaiting) {
  HostileDir d("output");
  const std::string fifo = d.fifo("pipe");
  const std::string dir = d.subdir("folder");
  HangGuard guard("OutputFile::open on a FIFO");
  OutputFile f;
  std::string error;
  EXPECT_FALSE(f.open(fifo, "trace", OutputMode::kReplace, error));
  expect_words(error, {fifo + ": cannot write the trace: ", "a FIFO, not a regular file"});
  EXPECT_FALSE(f.open(dir, "graph", OutputMode::kReplace, error));
  expect_words(error, {dir + ": cannot write the graph: ", "a directory"});
  EXPECT_FALSE(f.open("/dev/null", "key file", OutputMode::kNewPrivate, error));
  expect_words(error, {"/dev/null: ", "a character device"});
  EXPECT_FALSE(f.open(d.path("no/such/folder/x.json"), "trace", OutputMode::kReplace, error));
  expect_words(error, {d.path("no/such/folder/x.json") + ": cannot write the trace: ", "No such file or directory"});
  EXPECT_FALSE(f.is_open());
  EXPECT_EQ(entries(d.dir()).size(), 2u) << "only the FIFO and the folder";
}

// As a full disk would: the write fails (EFBIG under a file size limit, with SIGXFSZ
// ignored as the tools ignore it), the error says why, and nothing is left.
TEST(OutputFileTest, AFailedWriteLeavesNoFileAndSaysWhy) {
  HostileDir d("output");
  const std::string p = d.path("net.key");
  OutputFile f;
  std::string error;
  ASSERT_TRUE(f.open(p, "key file", OutputMode::kNewPrivate, error)) << error;
  struct rlimit old {};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  struct sigaction ignore {
  }, before{};
  ignore.sa_handler = SIG_IGN;
  ::sigaction(SIGXFSZ, &ignore, &before);
  struct rlimit small = old;
  small.rlim_cur = 16;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
  const bool written = f.write(std::string(100, 'k'), error);
  ::setrlimit(RLIMIT_FSIZE, &old);
  ::sigaction(SIGXFSZ, &before, nullptr);
  EXPECT_FALSE(written);
  expect_words(error, {p + ": cannot write the key file: ", std::strerror(EFBIG), "after 16 bytes"});
  EXPECT_FALSE(f.is_open());
  EXPECT_FALSE(f.commit(error)) << "nothing to commit after a failed write";
  EXPECT_TRUE(entries(d.dir()).empty()) << "left: " << (entries(d.dir()).empty() ? "" : entries(d.dir())[0]);
}

TEST(OutputFileTest, APrivateFileIsMode0600AndNeverReplacesOne) {
  HostileDir d("output");
  const std::string p = d.path("net.key");
  std::string error;
  OutputFile f;
  ASSERT_TRUE(f.open(p, "key file", OutputMode::kNewPrivate, error)) << error;
  ASSERT_TRUE(f.write("secret\n", error));
  ASSERT_TRUE(f.commit(error)) << error;
  struct stat st {};
  ASSERT_EQ(::stat(p.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0600u);
  // There already: refused at open().
  EXPECT_FALSE(f.open(p, "key file", OutputMode::kNewPrivate, error));
  expect_words(error, {p + ": cannot write the key file: it exists (not overwritten)"});
  // Appeared between open() and commit() (another keygen): still not replaced.
  const std::string q = d.path("other.key");
  ASSERT_TRUE(f.open(q, "key file", OutputMode::kNewPrivate, error)) << error;
  ASSERT_TRUE(f.write("mine\n", error));
  d.write("other.key", "theirs\n");
  EXPECT_FALSE(f.commit(error));
  expect_words(error, {q + ": cannot write the key file: it exists (not overwritten)"});
  EXPECT_EQ(contents(q), "theirs\n");
  EXPECT_EQ(entries(d.dir()).size(), 2u) << "no temporary file left";
}

}  // namespace
}  // namespace rack::rt
