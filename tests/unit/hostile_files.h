// Hostile files for the reader tests (issue 17): a FIFO nobody writes, a directory, a
// character device, a file of a given size, and a guard that ends the test binary
// with a message when a read hangs (a FIFO must be refused, never waited on).
//
// Test code; nothing here is RT-safe.
#pragma once

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

namespace rack::test {

// Ends the process (exit 3) with a message when the guarded scope takes longer than
// `seconds`: a reader that blocks on a FIFO would otherwise hang the test until
// ctest's TIMEOUT, without saying where. Generous by design (a watchdog, not a timing).
class HangGuard {
 public:
  explicit HangGuard(const char* what, unsigned seconds = 20) {
    std::strncpy(what_, what, sizeof what_ - 1);
    struct sigaction sa {};
    sa.sa_handler = &HangGuard::fire;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGALRM, &sa, &old_);
    ::alarm(seconds);
  }
  ~HangGuard() {
    ::alarm(0);
    ::sigaction(SIGALRM, &old_, nullptr);
  }
  HangGuard(const HangGuard&) = delete;
  HangGuard& operator=(const HangGuard&) = delete;

 private:
  static void fire(int) {
    static constexpr char kHead[] = "\nWATCHDOG: a reader hung on: ";
    (void)!::write(2, kHead, sizeof kHead - 1);
    (void)!::write(2, what_, std::strlen(what_));
    (void)!::write(2, "\n", 1);
    ::_exit(3);
  }
  static inline char what_[200] = {};
  struct sigaction old_ {};
};

// A scratch folder per test, removed at the end.
class HostileDir {
 public:
  explicit HostileDir(const std::string& tag) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("rack-hostile-" + tag + "-" + std::to_string(::getpid()) + "-" + (info != nullptr ? info->name() : "x"));
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
  }
  ~HostileDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }
  [[nodiscard]] std::string dir() const { return dir_.string(); }
  std::string write(const std::string& name, const std::string& bytes) const {
    std::ofstream(dir_ / name, std::ios::binary) << bytes;
    return path(name);
  }
  // A FIFO with no writer: opening it for reading without O_NONBLOCK would block.
  std::string fifo(const std::string& name) const {
    const std::string p = path(name);
    EXPECT_EQ(::mkfifo(p.c_str(), 0600), 0) << p << ": " << std::strerror(errno);
    return p;
  }
  std::string subdir(const std::string& name) const {
    std::filesystem::create_directories(dir_ / name);
    return path(name);
  }
  // A sparse file of `bytes` (no disk used): larger than every reader's limit.
  std::string sparse(const std::string& name, uint64_t bytes) const {
    const std::string p = write(name, "");
    std::filesystem::resize_file(p, bytes);
    return p;
  }

 private:
  std::filesystem::path dir_;
};

}  // namespace rack::test
