// The PM QoS hold: while held, /dev/cpu_dma_latency reads back our bound (the
// kernel's current minimum over all holders).
#include "rack/rt/pm_qos.h"

#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdint>

namespace rack::rt {
namespace {

// The kernel's current bound in us, or -1 when unreadable.
int32_t current_bound() {
  const int fd = ::open("/dev/cpu_dma_latency", O_RDONLY | O_CLOEXEC);
  if (fd < 0) return -1;
  int32_t v = -1;
  const bool ok = ::read(fd, &v, sizeof v) == static_cast<ssize_t>(sizeof v);
  ::close(fd);
  return ok ? v : -1;
}

TEST(CpuLatencyHoldTest, HoldsTheBoundWhileAliveAndReleasesIt) {
  if (::access("/dev/cpu_dma_latency", W_OK) != 0) {
    GTEST_SKIP() << "/dev/cpu_dma_latency is not writable here (needs root and a kernel with PM QoS); "
                    "the refusal path is covered by NegativeBoundHoldsNothing";
  }
  const int32_t before = current_bound();
  ASSERT_GE(before, 0);
  {
    CpuLatencyHold hold(0);
    ASSERT_TRUE(hold.active()) << hold.describe();
    EXPECT_EQ(current_bound(), 0);
    EXPECT_NE(hold.describe().find("held at 0 us"), std::string::npos) << hold.describe();
  }
  // That ours is released on close is the kernel's contract; it is not checked here
  // because other holders (rackd processes of concurrent tests, cyclictest) come and go.
}

TEST(CpuLatencyHoldTest, NegativeBoundHoldsNothing) {
  CpuLatencyHold hold(-1);
  EXPECT_FALSE(hold.active());
  EXPECT_EQ(hold.error(), 0);
  EXPECT_NE(hold.describe().find("left to the system"), std::string::npos) << hold.describe();
}

}  // namespace
}  // namespace rack::rt
