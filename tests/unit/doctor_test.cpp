// rackctl doctor's checks against fake /proc, /sys and /dev trees: each check's
// verdict and that every problem comes with its fix.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "doctor.h"

namespace rack::tools {
namespace {

namespace fs = std::filesystem;

constexpr const char*
    kLimitsHeader = "Limit                     Soft Limit           Hard Limit           Units     \n";

class DoctorTest : public ::testing::Test {
 protected:
  DoctorTest() {
    root_ = fs::temp_directory_path() / ("rack-doctor-" + std::to_string(::getpid()) + "-" +
                                         ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    // A healthy host: limits granted, no capabilities, a multicast route on eth0.
    write("proc/self/limits", std::string(kLimitsHeader) +
                                  "Max locked memory         unlimited            unlimited            bytes     \n"
                                  "Max realtime priority     99                   99                   \n");
    write("proc/self/status", "Name:\trackctl\nCapEff:\t0000000000000000\n");
    write("proc/net/route",
          "Iface\tDestination\tGateway \tFlags\tRefCnt\tUse\tMetric\tMask\t\tMTU\tWindow\tIRTT\n"
          "eth0\t00000000\t0102A8C0\t0003\t0\t0\t0\t00000000\t0\t0\t0\n"
          "eth0\t0002A8C0\t00000000\t0001\t0\t0\t0\t00FFFFFF\t0\t0\t0\n");
    write("sys/class/net/eth0/flags", "0x1003\n");
    write("sys/class/net/lo/flags", "0x9\n");
    write("proc/sys/net/core/rmem_max", "4194304\n");
    write("sys/kernel/realtime", "1\n");
    write("proc/version", "Linux version 6.1.0-27-rt-amd64 #1 SMP PREEMPT_RT Debian 6.1.115-1\n");
    write("dev/cpu_dma_latency", "");
    write("sys/devices/system/clocksource/clocksource0/current_clocksource", "tsc\n");
    write("sys/devices/system/clocksource/clocksource0/available_clocksource", "tsc hpet acpi_pm \n");
  }
  ~DoctorTest() override { fs::remove_all(root_); }

  void write(const std::string& rel, const std::string& text) {
    const auto p = root_ / rel;
    fs::create_directories(p.parent_path());
    std::ofstream(p) << text;
  }
  DoctorCheck check(const std::string& name) {
    DoctorInput in;
    in.root = root_;
    for (auto& c : run_doctor(in)) {
      if (c.name == name) return c;
    }
    ADD_FAILURE() << "no check " << name;
    return {};
  }

  fs::path root_;
};

TEST_F(DoctorTest, AHealthyHostPassesEveryCheck) {
  DoctorInput in;
  in.root = root_;
  const auto checks = run_doctor(in);
  ASSERT_EQ(checks.size(), 7u);
  for (const auto& c : checks) {
    EXPECT_EQ(c.verdict, Verdict::kOk) << c.name << ": " << c.found;
    EXPECT_TRUE(c.fix.empty()) << c.name;
  }
  const std::string text = format_doctor(checks);
  EXPECT_NE(text.find("ok   multicast-route  239.255.76.67 goes to eth0 (default route)"), std::string::npos) << text;
  EXPECT_NE(doctor_json(checks).find("{\"check\":\"rt-priority\",\"verdict\":\"ok\""), std::string::npos);
}

TEST_F(DoctorTest, NoRtPriorityFailsAndALowOneWarns) {
  write("proc/self/limits", std::string(kLimitsHeader) + "Max realtime priority     0                    0\n");
  DoctorCheck c = check("rt-priority");
  EXPECT_EQ(c.verdict, Verdict::kFail) << c.found;
  EXPECT_NE(c.found.find("ulimit -r 0"), std::string::npos) << c.found;
  EXPECT_NE(c.fix.find("rtprio 99"), std::string::npos) << c.fix;
  write("proc/self/limits", std::string(kLimitsHeader) + "Max realtime priority     50                   50\n");
  c = check("rt-priority");
  EXPECT_EQ(c.verdict, Verdict::kWarn) << c.found;
  EXPECT_NE(c.found.find("above 50"), std::string::npos) << c.found;
  // CAP_SYS_NICE (bit 23) overrides the limit.
  write("proc/self/status", "CapEff:\t0000000000800000\n");
  EXPECT_EQ(check("rt-priority").verdict, Verdict::kOk);
}

TEST_F(DoctorTest, LimitedMemlockFailsUnlessCapIpcLock) {
  write("proc/self/limits", std::string(kLimitsHeader) +
                                "Max locked memory         8388608              8388608              bytes\n"
                                "Max realtime priority     99                   99\n");
  DoctorCheck c = check("memlock");
  EXPECT_EQ(c.verdict, Verdict::kFail);
  EXPECT_NE(c.found.find("ulimit -l 8192 KiB"), std::string::npos) << c.found;
  EXPECT_NE(c.fix.find("memlock unlimited"), std::string::npos) << c.fix;
  write("proc/self/status", "CapEff:\t0000000000004000\n");  // CAP_IPC_LOCK, bit 14
  EXPECT_EQ(check("memlock").verdict, Verdict::kOk);
}

TEST_F(DoctorTest, UnreadableLimitsWarnWithWhere) {
  fs::remove(root_ / "proc/self/limits");
  const DoctorCheck c = check("memlock");
  EXPECT_EQ(c.verdict, Verdict::kWarn);
  EXPECT_NE(c.found.find((root_ / "proc/self/limits").string()), std::string::npos) << c.found;
  EXPECT_FALSE(c.fix.empty());
}

TEST_F(DoctorTest, MulticastRouteMissingDownOrExplicit) {
  // Only the local network: nothing covers 239.255.76.67.
  write("proc/net/route",
        "Iface\tDestination\tGateway \tFlags\tRefCnt\tUse\tMetric\tMask\t\tMTU\tWindow\tIRTT\n"
        "eth0\t0002A8C0\t00000000\t0001\t0\t0\t0\t00FFFFFF\t0\t0\t0\n");
  DoctorCheck c = check("multicast-route");
  EXPECT_EQ(c.verdict, Verdict::kFail) << c.found;
  EXPECT_NE(c.fix.find("ip route add 224.0.0.0/4"), std::string::npos) << c.fix;
  // 224.0.0.0/4 on lo, which is up but not multicast-capable (flags 0x9).
  write("proc/net/route",
        "Iface\tDestination\tGateway \tFlags\tRefCnt\tUse\tMetric\tMask\t\tMTU\tWindow\tIRTT\n"
        "lo\t000000E0\t00000000\t0001\t0\t0\t0\t000000F0\t0\t0\t0\n");
  c = check("multicast-route");
  EXPECT_EQ(c.verdict, Verdict::kFail) << c.found;
  EXPECT_NE(c.found.find("lo, which is not multicast-capable"), std::string::npos) << c.found;
  EXPECT_NE(c.fix.find("ip link set lo up multicast on"), std::string::npos) << c.fix;
  write("sys/class/net/lo/flags", "0x1009\n");
  c = check("multicast-route");
  EXPECT_EQ(c.verdict, Verdict::kOk) << c.found;
  EXPECT_NE(c.found.find("goes to lo (up, multicast)"), std::string::npos) << c.found;
  // A route that is not UP does not count.
  write("proc/net/route",
        "Iface\tDestination\tGateway \tFlags\tRefCnt\tUse\tMetric\tMask\t\tMTU\tWindow\tIRTT\n"
        "lo\t000000E0\t00000000\t0000\t0\t0\t0\t000000F0\t0\t0\t0\n");
  EXPECT_EQ(check("multicast-route").verdict, Verdict::kFail);
}

TEST_F(DoctorTest, MulticastRouteUsesTheGivenGroup) {
  write("proc/net/route",
        "Iface\tDestination\tGateway \tFlags\tRefCnt\tUse\tMetric\tMask\t\tMTU\tWindow\tIRTT\n"
        "eth0\t000000EF\t00000000\t0001\t0\t0\t0\t000000FF\t0\t0\t0\n");  // 239.0.0.0/8
  DoctorInput in;
  in.root = root_;
  in.multicast_group = "239.1.2.3";
  EXPECT_EQ(run_doctor(in)[2].verdict, Verdict::kOk) << run_doctor(in)[2].found;
  in.multicast_group = "225.1.2.3";
  EXPECT_EQ(run_doctor(in)[2].verdict, Verdict::kFail);
  in.multicast_group = "not-an-address";
  EXPECT_EQ(run_doctor(in)[2].verdict, Verdict::kWarn);
}

TEST_F(DoctorTest, SmallRmemMaxWarnsWithTheSysctl) {
  write("proc/sys/net/core/rmem_max", "212992\n");
  const DoctorCheck c = check("rmem-max");
  EXPECT_EQ(c.verdict, Verdict::kWarn);
  EXPECT_NE(c.found.find("212992"), std::string::npos) << c.found;
  EXPECT_NE(c.fix.find("sysctl -w net.core.rmem_max=2097152"), std::string::npos) << c.fix;
}

TEST_F(DoctorTest, NonRtKernelWarns) {
  fs::remove(root_ / "sys/kernel/realtime");
  write("proc/version", "Linux version 6.1.0-27-amd64 #1 SMP PREEMPT_DYNAMIC Debian 6.1.115-1\n");
  const DoctorCheck c = check("preempt-rt");
  EXPECT_EQ(c.verdict, Verdict::kWarn);
  EXPECT_NE(c.found.find("6.1.0-27-amd64"), std::string::npos) << c.found;
  EXPECT_NE(c.fix.find("linux-image-rt-amd64"), std::string::npos) << c.fix;
  // /proc/version alone identifies an RT kernel too.
  write("proc/version", "Linux version 6.1.0-27-rt-amd64 #1 SMP PREEMPT_RT Debian\n");
  EXPECT_EQ(check("preempt-rt").verdict, Verdict::kOk);
}

TEST_F(DoctorTest, MissingCpuDmaLatencyWarns) {
  fs::remove(root_ / "dev/cpu_dma_latency");
  const DoctorCheck c = check("cpu-dma-latency");
  EXPECT_EQ(c.verdict, Verdict::kWarn);
  EXPECT_NE(c.found.find("does not exist"), std::string::npos) << c.found;
  EXPECT_FALSE(c.fix.empty());
}

TEST_F(DoctorTest, NotWritableCpuDmaLatencyWarnsWithTheUdevRule) {
  if (::geteuid() == 0) GTEST_SKIP() << "root may write any file: the not-writable case needs a normal user";
  ::chmod((root_ / "dev/cpu_dma_latency").c_str(), 0444);
  const DoctorCheck c = check("cpu-dma-latency");
  EXPECT_EQ(c.verdict, Verdict::kWarn);
  EXPECT_NE(c.fix.find("udev"), std::string::npos) << c.fix;
}

TEST_F(DoctorTest, SlowClockSourceWarnsWithTheAvailableOnes) {
  write("sys/devices/system/clocksource/clocksource0/current_clocksource", "hpet\n");
  const DoctorCheck c = check("clocksource");
  EXPECT_EQ(c.verdict, Verdict::kWarn);
  EXPECT_NE(c.found.find("hpet"), std::string::npos) << c.found;
  EXPECT_NE(c.fix.find("available: tsc hpet acpi_pm"), std::string::npos) << c.fix;
  write("sys/devices/system/clocksource/clocksource0/current_clocksource", "kvm-clock\n");
  EXPECT_EQ(check("clocksource").verdict, Verdict::kOk);
}

TEST_F(DoctorTest, AnEmptyRootWarnsEverywhereAndNeverCrashes) {
  fs::remove_all(root_);
  fs::create_directories(root_);
  DoctorInput in;
  in.root = root_;
  const auto checks = run_doctor(in);
  ASSERT_EQ(checks.size(), 7u);
  for (const auto& c : checks) {
    EXPECT_NE(c.verdict, Verdict::kOk) << c.name;
    EXPECT_FALSE(c.fix.empty()) << c.name;
  }
}

}  // namespace
}  // namespace rack::tools
