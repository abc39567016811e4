// Issue 17: files named by a host file that are hostile (a FIFO, /dev/zero, a header
// that promises gigabytes) must not take rackd down or stall it. The start-up regime
// decides what follows: a component whose init() refuses its file goes to ERROR with
// the reason (file and byte) while the others run; a plug-in path is part of the host
// file, so a bad one is a host-file error (exit 2, file:line:col). The tools likewise:
// rack-backtrace and rack-foxglove refuse FIFOs and devices where files belong, and
// rackd, rackctl and gdos refuse numbers they cannot keep (exit 2, saying what).
#include <gtest/gtest.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mini_json.h"
#include "process.h"

namespace rack::test {
namespace {

using namespace std::chrono_literals;

const std::string kRackd = RACK_RACKD_PATH;
const std::string kRackctl = RACK_RACKCTL_PATH;
const std::string kBacktrace = RACK_BACKTRACE_PATH;
const std::string kGdos = RACK_GDOS_PATH;
const std::string kGui = RACK_GUI_PATH;

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

class HostileFilesTest : public ::testing::Test {
 protected:
  HostileFilesTest() : watchdog_(100s, ::testing::UnitTest::GetInstance()->current_test_info()->name()) {}

  std::string fifo(const std::string& name) {
    const std::string p = (dir_.path() / name).string();
    EXPECT_EQ(::mkfifo(p.c_str(), 0600), 0) << p;
    return p;
  }
  std::string state_of(const std::string& name) {
    const RunResult r = run({kRackctl, "--lcm", bus_.url(), "--discover-ms", "3000", "status", name, "--json"}, 30s);
    if (r.exit_code != 0) return "";
    const auto j = parse_json(r.out);
    const Json* s = j ? j->get("state") : nullptr;
    return s != nullptr && s->is_string() ? s->string : "";
  }
  template <typename Pred>
  bool eventually(Pred pred, std::chrono::milliseconds bound = 20s) {
    const auto deadline = std::chrono::steady_clock::now() + bound;
    for (;;) {
      if (pred()) return true;
      if (std::chrono::steady_clock::now() >= deadline) return false;
      std::this_thread::sleep_for(50ms);
    }
  }

  Watchdog watchdog_;
  TempDir dir_;
  LcmBus bus_;
};

// Before issue 17 the FIFO map image hung rackd in loading (SIGTERM ignored), /dev/zero
// grew it to gigabytes and the 22-byte PGM allocated 900 MB.
TEST_F(HostileFilesTest, HostileMapsAndLogsPutTheirComponentInErrorAndTheRestRuns) {
  const std::string fifo_pgm = fifo("fifo.pgm");
  const std::string fifo_log = fifo("fifo.log");
  const std::string fifo_out = fifo("fifo_out.txt");
  const std::string
      map_tail = "resolution: 0.05\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n";
  const auto fifo_map = dir_.write("fifo_map.yaml", "image: " + fifo_pgm + "\n" + map_tail);
  const auto zero_map = dir_.write("zero_map.yaml", "image: /dev/zero\n" + map_tail);
  dir_.write("huge.pgm", "P5\n30000 30000\n255\n\xff\xff");
  const auto huge_map = dir_.write("huge_map.yaml", "image: huge.pgm\n" + map_tail);
  std::string host = "host: hostile-files\nsystem: 0\nlcm: true\nlcm_url: \"" + bus_.url() +
                     "\"\nheap_prefault_mib: 8\n"
                     "components:\n"
                     "  - name: generator\n    class: Generator\n    instance: 0\n    autostart: true\n"
                     "    data_task: {priority: 60, period_ms: 10}\n"
                     "  - name: chassis\n    class: ChassisReplay\n    instance: 0\n    autostart: false\n"
                     "    data_task: {priority: 61, period_ms: 10}\n    params:\n      log: " +
                     fifo_log +
                     "\n"
                     "  - name: traj\n    class: TrajectoryWriter\n    instance: 0\n    autostart: false\n"
                     "    params:\n      source: chassis\n      file: " +
                     fifo_out + "\n";
  const std::pair<std::string, std::string> ladars[] = {
      {"ladar_fifo", fifo_map.string()}, {"ladar_zero", zero_map.string()}, {"ladar_huge", huge_map.string()}};
  int instance = 0;
  for (const auto& [name, map] : ladars) {
    host += "  - name: " + name + "\n    class: LadarSim\n    instance: " + std::to_string(instance++) +
            "\n    autostart: false\n    data_task: {priority: 62, period_ms: 40}\n    params:\n      map: " + map +
            "\n      chassis: chassis\n";
  }
  Process d({kRackd, dir_.write("hostile.yaml", host).string(), "--lcm", bus_.url()}, dir_.path(), "rackd");
  ASSERT_TRUE(d.wait_for_stderr("rackd: running", 30s)) << d.err();
  const std::string err = d.err();
  EXPECT_TRUE(contains(err, fifo_log + ": the log file is a FIFO, not a regular file")) << err;
  EXPECT_TRUE(contains(err, fifo_pgm + ": the map image is a FIFO, not a regular file")) << err;
  EXPECT_TRUE(contains(err, "/dev/zero: the map image is a character device, not a regular file")) << err;
  EXPECT_TRUE(contains(err, "huge.pgm: byte 18: 30000x30000 = 900000000 pixels, more than the limit")) << err;
  EXPECT_TRUE(contains(err, fifo_out + ": the trajectory output is a FIFO, not a regular file")) << err;
  for (const char* name : {"chassis", "ladar_fifo", "ladar_zero", "ladar_huge", "traj"})
    EXPECT_EQ(state_of(name), "ERROR") << name;
  EXPECT_TRUE(eventually([&] { return state_of("generator") == "ENABLED"; }));
  d.signal(SIGTERM);
  EXPECT_EQ(d.wait_exit(20s), std::optional<int>(0)) << d.err();
}

TEST_F(HostileFilesTest, APluginThatIsAFifoIsAHostFileErrorNotAHang) {
  const std::string plugin = fifo("plugin.so");
  const auto host = dir_.write("plugin.yaml",
                               "host: p\nsystem: 0\nplugins:\n  - " + plugin +
                                   "\ncomponents:\n  - name: g\n    class: Generator\n    instance: 0\n");
  const RunResult r = run({kRackd, "--check", host.string()}, 30s);
  EXPECT_FALSE(r.timed_out) << r.describe();
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_TRUE(contains(r.err, host.string() + ":4:")) << r.describe();
  EXPECT_TRUE(contains(r.err, plugin + ": the plug-in is a FIFO, not a regular file")) << r.describe();
}

// A report names its modules by path, and reports are copied from other machines: a
// FIFO (or a device) where a binary was is refused before libdwfl opens it (open()
// waited for a writer for ever), and the frames stay unsymbolized.
TEST_F(HostileFilesTest, AReportNamingAFifoAsItsBinaryIsRefusedNotWaitedOn) {
  const std::string binary = fifo("rackd");
  const auto report = dir_.write(
      "fifo.report",
      "RACK-MODESWITCH-REPORT 1 program=rackd pid=4242 start_ns=1 exe=" + binary +
          "\nmodule 0 base=0x55d0c0000000 lo=0x55d0c000d000 hi=0x55d0c0062000 build_id=76acf9 path=" + binary +
          "\nreport 1 reason=SYSCALL mode=warn task=demo:cmd component=demo label=ModeSwitchDemo(0/0) tid=4245 "
          "time_ns=5 syscall=1 frames=1\nframe 0 0x55d0c000e000 rackd+0xe000\nend 1\n");
  const RunResult r = run({kBacktrace, report.string()}, 30s);
  EXPECT_FALSE(r.timed_out) << r.describe();
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "module 0: " + binary + ": the module file is a FIFO, not a regular file"))
      << r.describe();
  EXPECT_TRUE(contains(r.out, "SYSCALL")) << r.describe();  // the report itself is still shown
}

// rack-foxglove play and --record name files too: a FIFO (or /dev/zero) to play, or a
// FIFO to record into, is refused with what it is (readFileSync waited for ever on the
// FIFO and read /dev/zero until memory ran out; opening a FIFO to write waited for a
// reader), exit 2 before rack-gui is even asked.
TEST_F(HostileFilesTest, RackFoxgloveRefusesAFifoToPlayOrToRecordInto) {
  const auto node = find_program("node");
  if (!node) GTEST_SKIP() << "node is not installed (Debian: apt-get install nodejs); scripts/setup.sh installs it";
  const std::string foxglove = std::string(RACK_SOURCE_DIR) + "/tools/foxglove";
  if (!std::filesystem::exists(foxglove + "/node_modules/@mcap/core")) {
    GTEST_SKIP() << "tools/foxglove's packages are missing: npm ci in " << foxglove << " (scripts/setup.sh does)";
  }
  const std::string recording = fifo("rec.mcap");
  const std::string gui = "ws://127.0.0.1:9";  // never reached: the file is refused first
  for (const std::string& file : {recording, std::string("/dev/zero")}) {
    const RunResult r = run({*node, foxglove + "/rack-foxglove.mjs", "play", file, "--gui", gui}, 30s);
    EXPECT_FALSE(r.timed_out) << r.describe();
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    EXPECT_TRUE(contains(r.err, "play " + file + ": refused: cannot read it: a " +
                                    (file == recording ? "FIFO" : "character device") + ", not a regular file"))
        << r.describe();
  }
  const RunResult rec = run(
      {*node, foxglove + "/rack-foxglove.mjs", "--no-server", "--record", recording, "--gui", gui}, 30s);
  EXPECT_FALSE(rec.timed_out) << rec.describe();
  EXPECT_EQ(rec.exit_code, 2) << rec.describe();
  EXPECT_TRUE(contains(rec.err, "--record " + recording + ": a FIFO, not a regular file")) << rec.describe();
}

// Seconds and periods on the command line are bounded: strtod's "" (0), NaN, inf and
// 1e300 were taken, and the last two overflowed a deadline in ns (rackd and gdos
// stopped at once, silently; rackctl sent an unspecified period).
TEST_F(HostileFilesTest, DurationsAndPeriodsOutOfRangeAreUsageErrors) {
  const auto host = dir_.write("h.yaml", "host: h\nsystem: 0\ncomponents: []\n");
  for (const char* d : {"", "nan", "inf", "1e300", "-1", "5x"}) {
    const RunResult r = run({kRackd, "--check", host.string(), "--duration", d}, 30s);
    EXPECT_EQ(r.exit_code, 2) << d << ": " << r.describe();
    EXPECT_TRUE(contains(r.err, "rackd: --duration needs a number of seconds (0 to 1e+09), got '" + std::string(d)))
        << r.describe();
  }
  const RunResult status = run({kRackd, "--check", host.string(), "--status", "1e-12"}, 30s);
  EXPECT_EQ(status.exit_code, 2) << status.describe();
  EXPECT_TRUE(contains(status.err, "--status needs a number of seconds (0, or 0.01 to 1e+09)")) << status.describe();
  for (const char* d : {"inf", "1e300"}) {
    const RunResult r = run({kGdos, "--lcm", bus_.url(), "--duration", d}, 30s);
    EXPECT_EQ(r.exit_code, 2) << d << ": " << r.describe();
    EXPECT_TRUE(contains(r.err, "--duration needs seconds in (0, 1e9]")) << r.describe();
  }
  const RunResult count = run({kGdos, "--lcm", bus_.url(), "--count", "99999999999999999999"}, 30s);
  EXPECT_EQ(count.exit_code, 2) << count.describe();
  EXPECT_TRUE(contains(count.err, "--count needs a positive number")) << count.describe();
  const RunResult period = run(
      {kRackctl, "--lcm", bus_.url(), "watch", "Generator(0/0)", "--period", "1e308", "--count", "1"}, 30s);
  EXPECT_EQ(period.exit_code, 2) << period.describe();
  EXPECT_TRUE(contains(period.err, "--period needs milliseconds in 0..86400000")) << period.describe();
  // A wait of INT64_MAX ms ended discovery at once ("no rackd answered within
  // 9223372036854775807 ms").
  const RunResult wait = run({kRackctl, "--lcm", bus_.url(), "--discover-ms", "9223372036854775807", "list"}, 30s);
  EXPECT_EQ(wait.exit_code, 2) << wait.describe();
  EXPECT_TRUE(contains(wait.err, "--discover-ms takes 0..86400000 ms")) << wait.describe();
  const RunResult timeout = run({kRackctl, "--lcm", bus_.url(), "--timeout", "86400001", "list"}, 30s);
  EXPECT_EQ(timeout.exit_code, 2) << timeout.describe();
  EXPECT_TRUE(contains(timeout.err, "--timeout takes 1..86400000 ms")) << timeout.describe();
}

// A client holding more connections than rack-gui has file descriptors: accept() failed
// at once, in a loop (a core spun, nothing said). Now rack-gui says so, tries again
// every 100 ms, and serves new connections once descriptors are free again.
TEST_F(HostileFilesTest, RackGuiOutOfDescriptorsSaysSoAndServesAgainLater) {
  Process gui({"/bin/sh", "-c", "ulimit -n 48 && exec \"$0\" --lcm \"$1\" --port 0", kGui, bus_.url()}, dir_.path(),
              "gui");
  ASSERT_TRUE(gui.wait_for_stderr("rack-gui: serving http://127.0.0.1:", 30s)) << gui.err();
  const std::string err = gui.err();
  const auto at = err.find("http://127.0.0.1:") + 17;
  const int port = std::atoi(err.c_str() + at);
  ASSERT_GT(port, 0) << err;
  const auto connect_to_gui = [port] {
    const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd >= 0 && ::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
      ::close(fd);
      return -1;
    }
    return fd;
  };
  std::vector<int> held;
  for (int i = 0; i < 100; ++i) {
    const int fd = connect_to_gui();
    if (fd >= 0) held.push_back(fd);
  }
  EXPECT_TRUE(gui.wait_for_stderr("rack-gui: cannot accept connections: Too many open files (trying again", 20s))
      << gui.err();
  for (const int fd : held) ::close(fd);
  // Served again: a new connection gets an HTTP answer.
  EXPECT_TRUE(eventually([&] {
    const int fd = connect_to_gui();
    if (fd < 0) return false;
    timeval tv{2, 0};
    ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    const std::string get = "GET / HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
    char buf[16] = {};
    const bool ok = ::send(fd, get.data(), get.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(get.size()) &&
                    ::recv(fd, buf, 8, MSG_WAITALL) == 8 && std::string(buf, 8) == "HTTP/1.1";
    ::close(fd);
    return ok;
  }));
  EXPECT_TRUE(gui.running()) << gui.err();
  gui.signal(SIGTERM);
  EXPECT_EQ(gui.wait_exit(20s), std::optional<int>(0)) << gui.err();
}

// rackctl writes files that later runs trust (a key file, a trace, a graph): through a
// temporary file beside the target, renamed when whole (rack/rt/output_file.h). A write
// that fails (here a file size limit, as a full disk) left a partial key file that the
// next keygen refused to replace and rackd refused to read; a FIFO as --out waited for
// a reader for ever; a directory was said only after the trace.
TEST_F(HostileFilesTest, RackctlLeavesNoPartialFileAndRefusesFifosAndDirectories) {
  const std::string key = (dir_.path() / "net.key").string();
  // `ulimit -f 0`: write() fails with EFBIG (rackctl ignores SIGXFSZ, which would kill it).
  RunResult r = run({"/bin/sh", "-c", "ulimit -f 0 && exec \"$0\" keygen \"$1\"", kRackctl, key}, 30s);
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, key + ": cannot write the key file: File too large")) << r.describe();
  EXPECT_TRUE(std::filesystem::is_empty(dir_.path())) << "a partial key file or a temporary file was left";
  // The next keygen is not refused by a leftover, and makes a whole key.
  r = run({kRackctl, "keygen", key}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  const std::string made = read_file(key);
  EXPECT_EQ(made.size() - made.find('\n') - 1, 65u) << made;  // a comment line, then 64 hex digits

  const std::string pipe = fifo("out.fifo");
  r = run({kRackctl, "keygen", pipe}, 30s);
  EXPECT_FALSE(r.timed_out) << r.describe();
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, pipe + ": cannot write the key file: it is a FIFO, not a regular file")) << r.describe();
  for (const std::string& out : {pipe, dir_.path().string()}) {
    r = run({kRackctl, "--lcm", bus_.url(), "trace", "--duration", "1", "--out", out, "all"}, 30s);
    EXPECT_FALSE(r.timed_out) << r.describe();
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    EXPECT_TRUE(contains(r.err, "--out " + out + ": cannot write the trace: it is a")) << r.describe();
    EXPECT_TRUE(contains(r.err, "not a regular file (nothing recorded)")) << r.describe();
  }
  const auto host = dir_.write("h.yaml", "host: h\nsystem: 0\ncomponents: []\n");
  r = run({kRackctl, "graph", "--rackd", kRackd, "--out", pipe, host.string()}, 30s);
  EXPECT_FALSE(r.timed_out) << r.describe();
  EXPECT_EQ(r.exit_code, 1) << r.describe();
  EXPECT_TRUE(contains(r.err, "--out " + pipe + ": cannot write the graph: it is a FIFO")) << r.describe();
  // '-' is standard output.
  r = run({kRackctl, "graph", "--rackd", kRackd, "--out", "-", host.string()}, 30s);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(contains(r.out, "digraph")) << r.describe();
}

// A bad value is quoted short in rackctl's messages, with its length: a 100 kB argument
// was echoed back whole (and a megabyte-long reason from a peer would have been too).
TEST_F(HostileFilesTest, RackctlQuotesAHugeBadValueShortWithItsLength) {
  const std::string huge(100000, '7');
  const std::vector<std::vector<std::string>> cases = {
      {kRackctl, "--timeout", huge, "list"},
      {kRackctl, "--" + std::string(100000, 'x')},
      {kRackctl, std::string(100000, 'c')},
      {kRackctl, "--lcm", bus_.url(), "--discover-ms", "0", "status", "Generator(" + huge + ")"},
      {kRackctl, "--lcm", bus_.url(), "--discover-ms", "0", "status", std::string(100000, 'n')},
  };
  for (const auto& args : cases) {
    const RunResult r = run(args, 30s);
    EXPECT_NE(r.exit_code, 0) << r.describe().substr(0, 300);
    EXPECT_LT(r.err.size(), 1000u) << r.err.substr(0, 300);
    EXPECT_TRUE(contains(r.err, "... (1000")) << "its length is not said: " << r.err.substr(0, 300);
  }
}

}  // namespace
}  // namespace rack::test
