// Tool addresses (rack/tims/tool_address.h): claims on one machine never share a
// block, a claim ends with its holder (also SIGKILL), and the addresses stay on the
// tool system clear of the transports' own.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "rack/tims/lcm_transport.h"
#include "rack/tims/router.h"
#include "rack/tims/tool_address.h"

namespace rack::tims {
namespace {

class ToolAddressTest : public ::testing::Test {
 protected:
  void SetUp() override {
    registry_ = (std::filesystem::temp_directory_path() /
                 ("rack_tool_address_test_" + std::to_string(getpid()) + "_" +
                  ::testing::UnitTest::GetInstance()->current_test_info()->name()))
                    .string();
  }
  void TearDown() override { std::filesystem::remove(registry_); }
  std::string registry_;
};

TEST_F(ToolAddressTest, ClaimsInOneProcessAreDistinctAndOnTheToolSystem) {
  std::vector<ToolAddressClaim> claims;
  std::set<uint32_t> addresses;
  for (int i = 0; i < 500; ++i) {
    claims.push_back(ToolAddressClaim::claim(registry_));
    EXPECT_EQ(claims.back().warning(), "");
    for (uint32_t m = 0; m < kToolMailboxes; ++m) {
      const Address a = claims.back().mailbox(m);
      EXPECT_EQ(a.system(), kToolSystem);
      EXPECT_EQ(a.class_id(), classes::kTool);
      EXPECT_NE(a.instance(), 0xFF) << a.str();  // the transports' uplinks and control mailbox
      EXPECT_NE(a.raw(), kTransportControlAddress.raw());
      EXPECT_TRUE(addresses.insert(a.raw()).second) << "address " << a.str() << " given twice";
    }
  }
}

// Locks bytes [from, to) of the registry as another holder would (a descriptor of its own).
bool lock_range(int fd, off_t from, off_t to, short type = F_WRLCK) {
  if (to <= from) return true;
  struct flock l {};
  l.l_type = type;
  l.l_whence = SEEK_SET;
  l.l_start = from;
  l.l_len = to - from;
  return fcntl(fd, F_OFD_SETLK, &l) == 0;
}

TEST_F(ToolAddressTest, AKilledHoldersBlockIsFreeAgainAndAHeldOneIsNeverGiven) {
  // A child claims, reports its block, and waits to be killed.
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const auto c = ToolAddressClaim::claim(registry_);
    const uint32_t b = c.block();
    (void)!write(fds[1], &b, sizeof b);
    pause();
    _exit(0);
  }
  uint32_t held = 0;
  ASSERT_EQ(read(fds[0], &held, sizeof held), static_cast<ssize_t>(sizeof held));
  close(fds[0]);
  close(fds[1]);
  // Every other block is held too (by one descriptor here): nothing is free.
  const int others = open(registry_.c_str(), O_RDWR | O_CLOEXEC);
  ASSERT_GE(others, 0);
  ASSERT_TRUE(lock_range(others, 0, held));
  ASSERT_TRUE(lock_range(others, held + 1, kToolBlocks));
  EXPECT_THROW(ToolAddressClaim::claim(registry_), std::runtime_error);
  // The kernel releases the killed holder's block: it is the only one free.
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  {
    const auto c = ToolAddressClaim::claim(registry_);
    EXPECT_EQ(c.block(), held);
    EXPECT_THROW(ToolAddressClaim::claim(registry_), std::runtime_error);  // held by `c` now
  }
  // Released with `c`, and one more freed by the other holder.
  const uint32_t freed = (held + 7) % kToolBlocks;
  ASSERT_TRUE(lock_range(others, freed, freed + 1, F_UNLCK));
  const auto a = ToolAddressClaim::claim(registry_);
  const auto b = ToolAddressClaim::claim(registry_);
  EXPECT_EQ((std::set<uint32_t>{a.block(), b.block()}), (std::set<uint32_t>{held, freed}));
  close(others);
}

TEST_F(ToolAddressTest, AnUnusableRegistryGivesARandomAddressAndSaysWhy) {
  const auto c = ToolAddressClaim::claim("/nonexistent-dir/registry.lock");
  EXPECT_NE(c.warning().find("/nonexistent-dir/registry.lock"), std::string::npos) << c.warning();
  EXPECT_LT(c.block(), kToolBlocks);
}

}  // namespace
}  // namespace rack::tims
