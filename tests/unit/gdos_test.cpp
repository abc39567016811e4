// GDOS: the compile-time format check, every conversion against snprintf, rings
// (drops counted, never blocking), order per source, levels (gdosLevel from the host
// file and by SET_PARAM), a log flood beside a periodic task, the viewer's filters
// and line formats, and the record file (round trip and rejection with offsets).
#include <gtest/gtest.h>

#include "hostile_files.h"
#include <unistd.h>

#include <atomic>
#include <cfloat>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "gdos_view.h"
#include "rack/components/class_ids.h"
#include "rack/core/data_component.h"
#include "rack/core/gdos.h"
#include "rack/interfaces/demo.h"
#include "test_support.h"

namespace rack {
namespace {

using gdos::ArgInfo;
using gdos::FormatError;
using gdos::Level;
using tims::Address;

// ---------------------------------------------------------------- the format check

// Compile-time: these are the checks a log call's format goes through.
static_assert(gdos::check_format_for<int>("%d") == FormatError::kOk);
static_assert(gdos::check_format_for<short>("%hd") == FormatError::kOk);
static_assert(gdos::check_format_for<bool>("%d") == FormatError::kOk);
static_assert(gdos::check_format_for<long>("%ld") == FormatError::kOk);
static_assert(gdos::check_format_for<std::size_t>("%zu") == FormatError::kOk);
static_assert(gdos::check_format_for<double>("%.3f") == FormatError::kOk);
static_assert(gdos::check_format_for<float>("%g") == FormatError::kOk);
static_assert(gdos::check_format_for<long double>("%Lf") == FormatError::kOk);
static_assert(gdos::check_format_for<const char*>("%s") == FormatError::kOk);
static_assert(gdos::check_format_for<std::string>("%s") == FormatError::kOk);
static_assert(gdos::check_format_for<Address>("%-12s") == FormatError::kOk);
static_assert(gdos::check_format_for<const void*>("%p") == FormatError::kOk);
static_assert(gdos::check_format_for<int, int, double>("%*.*f") == FormatError::kOk);
static_assert(gdos::check_format_for<>("100%%") == FormatError::kOk);

TEST(GdosFormatCheckTest, RejectsWhatPrintfWouldMisread) {
  // Each of these is a compile error in a log call; here the checker's verdicts.
  EXPECT_EQ(gdos::check_format_for<int>("%f"), FormatError::kArgumentTypeMismatch);  // RACK's %f bug
  EXPECT_EQ(gdos::check_format_for<double>("%d"), FormatError::kArgumentTypeMismatch);
  EXPECT_EQ(gdos::check_format_for<long>("%d"), FormatError::kArgumentTypeMismatch);  // 8 bytes for 4
  EXPECT_EQ(gdos::check_format_for<int>("%ld"), FormatError::kArgumentTypeMismatch);
  EXPECT_EQ(gdos::check_format_for<double>("%Lf"), FormatError::kArgumentTypeMismatch);
  EXPECT_EQ(gdos::check_format_for<int>("%s"), FormatError::kArgumentTypeMismatch);
  EXPECT_EQ(gdos::check_format_for<const char*>("%p"), FormatError::kArgumentTypeMismatch);
  EXPECT_EQ(gdos::check_format_for<const char*>("%d"), FormatError::kArgumentTypeMismatch);
  EXPECT_EQ(gdos::check_format_for<double>("%*f"), FormatError::kArgumentTypeMismatch);  // a double for *
  EXPECT_EQ(gdos::check_format_for<int>("%*f"), FormatError::kTooFewArguments);
  EXPECT_EQ(gdos::check_format_for<>("%d"), FormatError::kTooFewArguments);
  EXPECT_EQ((gdos::check_format_for<int, int>("%d")), FormatError::kTooManyArguments);
  EXPECT_EQ(gdos::check_format_for<int*>("%n"), FormatError::kUnknownConversion);
  EXPECT_EQ(gdos::check_format_for<>("%m"), FormatError::kUnknownConversion);
  EXPECT_EQ(gdos::check_format_for<int>("%k"), FormatError::kUnknownConversion);
  EXPECT_EQ(gdos::check_format_for<const char*>("%ls"), FormatError::kUnknownConversion);
  EXPECT_EQ(gdos::check_format_for<int>("%1$d"), FormatError::kPositionalArgument);
  EXPECT_EQ(gdos::check_format_for<>("50%"), FormatError::kIncompleteConversion);
  EXPECT_EQ(gdos::check_format_for<std::vector<int>>("%d"), FormatError::kUnsupportedArgument);
  enum class Scoped { kA };
  EXPECT_EQ(gdos::check_format_for<Scoped>("%d"), FormatError::kUnsupportedArgument);
}

// ---------------------------------------------------------------- every conversion

constexpr Address kLadar = Address::make(0, class_ids::kLadar, 1);

// The ring path: encode as an RT task would, then decode and format as the GDOS
// thread does.
template <class... Args>
std::string via_ring(gdos::Format<Args...> f, const Args&... a) {
  gdos::LogRing ring(4);
  gdos::LogSource src(kLadar, "ladar");
  EXPECT_TRUE(gdos::write_record(ring, &src, src.address(), Level::kInfo, f.c_str(), a...));
  const std::byte* p = ring.peek();
  if (p == nullptr) return "<nothing>";
  gdos::RecordHeader h;
  std::memcpy(&h, p, sizeof h);
  std::string out;
  EXPECT_TRUE(gdos::format_record(h, p + sizeof h, out)) << out;
  return out;
}

// The path of threads without a ring (values as passed).
template <class... Args>
std::string via_values(gdos::Format<Args...> f, const Args&... a) {
  std::string out;
  if constexpr (sizeof...(Args) == 0) {
    EXPECT_TRUE(gdos::format_values(f.c_str(), nullptr, 0, out));
  } else {
    const gdos::Value v[] = {gdos::to_value(a)...};
    EXPECT_TRUE(gdos::format_values(f.c_str(), v, sizeof...(Args), out)) << out;
  }
  return out;
}

#define EXPECT_LIKE_PRINTF(fmt, ...)                                                        \
  do {                                                                                      \
    char expected_[1024];                                                                   \
    std::snprintf(expected_, sizeof expected_, fmt __VA_OPT__(, ) __VA_ARGS__);             \
    EXPECT_EQ(via_ring(fmt __VA_OPT__(, ) __VA_ARGS__), std::string(expected_)) << (fmt);   \
    EXPECT_EQ(via_values(fmt __VA_OPT__(, ) __VA_ARGS__), std::string(expected_)) << (fmt); \
  } while (0)

TEST(GdosConversionTest, IntegersFormatLikePrintf) {
  EXPECT_LIKE_PRINTF("%d", 0);
  EXPECT_LIKE_PRINTF("%d %d", INT_MIN, INT_MAX);
  EXPECT_LIKE_PRINTF("%i|%5i|%-5i|%05i|%+i|% i", -42, 42, 42, 42, 42, 42);
  EXPECT_LIKE_PRINTF("%u %u", 0u, UINT_MAX);
  EXPECT_LIKE_PRINTF("%u", -1);  // an int for %u: printf shows its bits as unsigned
  EXPECT_LIKE_PRINTF("%x %X %#x %#X %08x", 0xbeefu, 0xbeefu, 0xbeefu, 0xbeefu, 0xbeefu);
  EXPECT_LIKE_PRINTF("%o %#o %.5o", 8u, 8u, 8u);
  EXPECT_LIKE_PRINTF("%.3d|%8.3d|%-8.3d|%.0d|", 7, -7, 7, 0);
  EXPECT_LIKE_PRINTF("%hhd %hhu %hd %hu", 300, 300, 70000, 70000);
  EXPECT_LIKE_PRINTF("%ld %ld %lu", LONG_MIN, LONG_MAX, ULONG_MAX);
  EXPECT_LIKE_PRINTF("%lld %llu %llx", LLONG_MIN, ULLONG_MAX, 0x123456789abcdefULL);
  EXPECT_LIKE_PRINTF("%zu %zd %zx", static_cast<std::size_t>(SIZE_MAX), static_cast<ssize_t>(-5), std::size_t{255});
  EXPECT_LIKE_PRINTF("%jd %ju %td", static_cast<intmax_t>(-9), static_cast<uintmax_t>(9), static_cast<ptrdiff_t>(-3));
  EXPECT_LIKE_PRINTF("%'d", 1234567);
  const char c = 'x';
  const unsigned char uc = 200;
  const short s = -12;
  const bool b = true;
  EXPECT_LIKE_PRINTF("%d %u %hd %d %d", c, uc, s, b, int8_t{-3});
  enum Plain { kSeven = 7 };
  EXPECT_LIKE_PRINTF("%d", kSeven);
}

TEST(GdosConversionTest, CharactersAndStringsFormatLikePrintf) {
  EXPECT_LIKE_PRINTF("%c|%5c|%-5c|", 'A', 'b', 'c');
  EXPECT_LIKE_PRINTF("%c", 65);
  EXPECT_LIKE_PRINTF("%s|%10s|%-10s|%.3s|%10.2s|%s|", "hello", "right", "left", "truncate", "ab", "");
  const char buffer[16] = "in a buffer";
  EXPECT_LIKE_PRINTF("[%s]", buffer);
  const std::string str = "a std::string";
  char expected[64];
  std::snprintf(expected, sizeof expected, "[%s]", str.c_str());
  EXPECT_EQ(via_ring("[%s]", str), expected);
  EXPECT_EQ(via_values("[%s]", str), expected);
  // A view that is not NUL-terminated: only its bytes.
  const std::string_view part = std::string_view("abcdef").substr(1, 3);
  EXPECT_EQ(via_ring("[%s|%5s|%.2s]", part, part, part), "[bcd|  bcd|bc]");
  EXPECT_EQ(via_values("[%s|%5s|%.2s]", part, part, part), "[bcd|  bcd|bc]");
  const char* null = nullptr;
  EXPECT_EQ(via_ring("%s", null), "(null)");  // as glibc prints it
  EXPECT_LIKE_PRINTF("100%% of %d%%", 5);
  EXPECT_LIKE_PRINTF("no conversions at all");
}

TEST(GdosConversionTest, FloatingPointFormatsLikePrintf) {
  EXPECT_LIKE_PRINTF("%f %f %f", 3.14159, -0.0, 1e300);
  EXPECT_LIKE_PRINTF("%.0f|%10.4f|%-10.2f|%+f|% f|%010.3f", 2.5, 3.14159, 2.0, 1.5, 1.5, -1.25);
  EXPECT_LIKE_PRINTF("%F %f %f", INFINITY, -INFINITY, NAN);
  EXPECT_LIKE_PRINTF("%e %E %.2e %12.3e", 12345.678, 0.000123, 9.999, -1e-300);
  EXPECT_LIKE_PRINTF("%g %g %g %G %#g %.10g", 0.0001, 1e20, 100000.0, 1e-10, 1.0, M_PI);
  EXPECT_LIKE_PRINTF("%a %A %.3a", 1.0, 0.1, 2.0 / 3.0);
  EXPECT_LIKE_PRINTF("%f %lf", 0.1f, 0.2);  // float promotes; %lf is %f
  EXPECT_LIKE_PRINTF("%g %g", DBL_MIN, DBL_MAX);
  const long double ld = 1.0L / 3.0L;
  EXPECT_LIKE_PRINTF("%Lf %.20Le %Lg", ld, ld, ld);
}

TEST(GdosConversionTest, PointersStarsAndMixturesFormatLikePrintf) {
  int x = 0;
  const void* p = &x;
  const void* nil = nullptr;
  EXPECT_LIKE_PRINTF("%p %p %20p %-20p|", p, nil, p, p);
  EXPECT_LIKE_PRINTF("%*d|%*d|%-*d|", 6, 42, -6, 42, 6, 42);
  EXPECT_LIKE_PRINTF("%.*f|%.*f|%*.*f|", 2, M_PI, -1, M_PI, 10, 3, M_PI);
  EXPECT_LIKE_PRINTF("%*.*s|", 8, 3, "abcdef");
  EXPECT_LIKE_PRINTF("cycle %llu: %s at %.3f m, %d/%d hits (%5.1f%%) [%c] %p", 123456789ULL, "scan", 12.3456, 17, 20,
                     85.0, 'Z', p);
}

TEST(GdosConversionTest, AddressArgumentPrintsAsItsName) {
  const Address a = Address::make(0, class_ids::kLadar, 1);
  EXPECT_EQ(via_ring("to %s", a), "to Ladar(0/1)");
  EXPECT_EQ(via_ring("[%12s][%-12s][%.5s]", a, a, a), "[  Ladar(0/1)][Ladar(0/1)  ][Ladar]");
  EXPECT_EQ(via_ring("%s", a.with_mailbox(3)), "Ladar(0/1)#3");
  EXPECT_EQ(via_values("to %s", a), "to Ladar(0/1)");
}

TEST(GdosConversionTest, LongStringsAreCutAndMarked) {
  const std::string big(1000, 'x');
  const std::string out = via_ring("%s", big);
  EXPECT_EQ(out, std::string(gdos::kMaxStringBytes, 'x') + " [cut]");
  // Several strings share the record: the later ones get what is left, never more.
  const std::string s2 = via_ring("%s %s %d", big, big, 5);
  EXPECT_LE(s2.size(), gdos::kPayloadBytes + 16);
  EXPECT_NE(s2.find(" 5"), std::string::npos) << "the fixed-size argument after the strings survives: " << s2;
}

// ---------------------------------------------------------------- rings and levels

TEST(GdosRingTest, FullRingDropsCountsAndTheNextRecordCarriesTheCount) {
  gdos::LogRing ring(4, "test ring");
  gdos::LogSource src(kLadar, "ladar");
  EXPECT_EQ(ring.capacity(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(gdos::write_record(ring, &src, kLadar, Level::kInfo, "r %d", i));
  for (int i = 0; i < 10; ++i) EXPECT_FALSE(gdos::write_record(ring, &src, kLadar, Level::kInfo, "r %d", i));
  EXPECT_EQ(ring.dropped(), 10u);
  for (int i = 0; i < 4; ++i) {
    ASSERT_NE(ring.peek(), nullptr);
    ring.pop();
  }
  EXPECT_EQ(ring.peek(), nullptr);
  EXPECT_TRUE(gdos::write_record(ring, &src, kLadar, Level::kInfo, "after"));
  gdos::RecordHeader h;
  std::memcpy(&h, ring.peek(), sizeof h);
  EXPECT_EQ(h.dropped_before, 10u);
}

TEST(GdosRingTest, RoundsCapacityUpToAPowerOfTwo) {
  EXPECT_EQ(gdos::LogRing(5).capacity(), 8u);
  EXPECT_EQ(gdos::LogRing(1).capacity(), 2u);
}

TEST(GdosLevelTest, ThresholdFiltersAndPrintAlwaysPasses) {
  gdos::LogSource src(kLadar, "ladar", Level::kWarning);
  EXPECT_TRUE(src.enabled(Level::kPrint));
  EXPECT_TRUE(src.enabled(Level::kError));
  EXPECT_TRUE(src.enabled(Level::kWarning));
  EXPECT_FALSE(src.enabled(Level::kInfo));
  EXPECT_FALSE(src.enabled(Level::kDetail));
  src.set_level(Level::kPrint);
  EXPECT_TRUE(src.enabled(Level::kPrint));
  EXPECT_FALSE(src.enabled(Level::kError));
  // Through log(): only enabled records reach the ring.
  gdos::LogRing ring(8);
  std::thread t([&] {
    gdos::bind_thread_ring(&ring);
    src.set_level(Level::kWarning);
    gdos::log(src, Level::kDetail, "no");
    gdos::log(src, Level::kInfo, "no");
    gdos::log(src, Level::kWarning, "yes %d", 1);
    gdos::log(src, Level::kPrint, "yes %d", 2);
  });
  t.join();
  EXPECT_EQ(ring.written(), 2u);
  for (const char* name : {"print", "error", "warning", "info", "detail"}) {
    const auto l = gdos::parse_level(name);
    ASSERT_TRUE(l.has_value()) << name;
    EXPECT_STREQ(gdos::describe(*l), name);
  }
  EXPECT_FALSE(gdos::parse_level("verbose").has_value());
}

TEST(GdosHubTest, KeepsTheOrderOfOneSourceAcrossItsTwoTasks) {
  test::Watchdog dog;
  gdos::Hub hub;
  gdos::LogRing& a = hub.make_ring(1024, "command task");
  gdos::LogRing& b = hub.make_ring(1024, "data task");
  gdos::LogSource src(kLadar, "ladar");
  // Two tasks of one component take turns (a causal chain), like an ON request
  // handled in the command task followed by loop() in the data task.
  constexpr int kRecords = 600;
  std::atomic<int> turn{0};
  auto task = [&](gdos::LogRing* ring, int parity) {
    gdos::bind_thread_ring(ring);
    for (int i = parity; i < kRecords; i += 2) {
      while (turn.load(std::memory_order_acquire) != i) std::this_thread::yield();
      gdos::log(src, Level::kInfo, "step %d", i);
      turn.store(i + 1, std::memory_order_release);
    }
  };
  std::thread ta(task, &a, 0), tb(task, &b, 1);
  // Drain while they run too: the merge must hold across passes.
  std::vector<std::string> texts;
  std::vector<uint64_t> sequences;
  auto sink = [&](const gdos::Record& r) {
    texts.emplace_back(r.text);
    sequences.push_back(r.sequence);
    EXPECT_EQ(r.name, "ladar");
    EXPECT_EQ(r.source, kLadar);
  };
  while (turn.load() < kRecords) hub.drain(sink);
  ta.join();
  tb.join();
  hub.drain(sink);
  ASSERT_EQ(texts.size(), static_cast<std::size_t>(kRecords));
  for (int i = 0; i < kRecords; ++i) {
    EXPECT_EQ(texts[static_cast<std::size_t>(i)], "step " + std::to_string(i));
    if (i > 0) {
      EXPECT_EQ(sequences[static_cast<std::size_t>(i)], sequences[static_cast<std::size_t>(i - 1)] + 1);
    }
  }
}

TEST(GdosHubTest, ThreadsWithoutARingQueueFormattedTextToTheProcessHub) {
  gdos::Hub hub;
  gdos::Hub::set_process_hub(&hub);
  gdos::LogSource src(kLadar, "ladar");
  std::thread t([&] { gdos::log(src, Level::kError, "from an unbound thread: %s %d", "x", 7); });
  t.join();
  hub.publish_text(Level::kWarning, kLadar, "ladar", "a preformatted report");
  std::vector<std::string> got;
  hub.drain([&](const gdos::Record& r) {
    got.emplace_back(std::string(gdos::describe(r.level)) + ": " + std::string(r.text));
  });
  gdos::Hub::set_process_hub(nullptr);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0], "error: from an unbound thread: x 7");
  EXPECT_EQ(got[1], "warning: a preformatted report");
  EXPECT_EQ(hub.counters().unbound, 1u);
}

TEST(GdosHubTest, LineFormatForStderr) {
  gdos::Record r;
  r.level = Level::kWarning;
  r.time_ns = 1'795'304'702'722'090'458;  // 2026-11-21T23:45:02.722090Z
  r.source = kLadar;
  r.name = "front";
  r.text = "hello";
  EXPECT_EQ(gdos::format_line(r), "2026-11-21T23:45:02.722090Z W front Ladar(0/1): hello\n");
}

// ---------------------------------------------------------------- in an executor

// Logs `burst` records per cycle from its periodic data task.
class LogFlood final : public DataComponent<interfaces::GeneratorData> {
 public:
  LogFlood()
      : DataComponent(DataTaskMode::kPeriodic),
        burst_(declare_int("burst", 0, {.doc = "records per cycle", .min = 0, .max = 100000})) {}
  std::atomic<uint64_t> calls{0};

 protected:
  HookResult loop() override {
    const int64_t n = burst_.get_int();
    for (int64_t i = 0; i < n; ++i) log_detail("flood record %lld of this cycle, %f", static_cast<long long>(i), 0.5);
    calls.fetch_add(static_cast<uint64_t>(n), std::memory_order_relaxed);
    log_info("cycle done");
    return HookResult::kOk;
  }

 private:
  Parameter& burst_;
};

class GdosExecutorTest : public ::testing::Test {
 protected:
  void start(const std::string& yaml) {
    ComponentClass cls;
    cls.impl = "LogFlood";
    cls.class_id = class_ids::kGenerator;
    cls.description = "test: floods its log";
    cls.make = [] { return std::unique_ptr<Component>(new LogFlood()); };
    registry_.add(std::move(cls));
    components::register_builtin(registry_);
    auto loaded = load_host_text(yaml, "gdos.yaml", registry_, rt::probe_capabilities());
    ASSERT_TRUE(loaded.errors.empty()) << loaded.errors.front().str();
    ExecutorOptions o;
    o.gdos_sink = [this](const gdos::Record& r) {
      std::lock_guard lock(mutex_);
      records_.push_back({r.level, std::string(r.name), std::string(r.text), r.sequence, r.dropped_before});
    };
    executor_ = std::make_unique<Executor>(std::move(loaded.host), std::move(o));
    executor_->start();
    reply_box_ = std::make_unique<tims::Mailbox>(Address::make(0, tims::classes::kTool, 9, 1), 4, 4096);
    executor_->router().add(*reply_box_);
    endpoint_ = std::make_unique<tims::Endpoint>(executor_->router(), *reply_box_, 10);
  }
  void TearDown() override {
    if (executor_) {
      executor_->stop();
      executor_->router().remove(reply_box_->address());
    }
  }
  int8_t call(Address dest, int8_t type, const void* body = nullptr, std::size_t size = 0) {
    alignas(8) std::byte buf[4096];
    const tims::ConstBuffer part{body, size};
    const auto r = endpoint_->call(dest, type, std::span<const tims::ConstBuffer>(&part, size == 0 ? 0 : 1), buf,
                                   test::kCallTimeoutNs);
    last_error_ = r.status == tims::CallStatus::kOk && r.reply.type == tims::msg::kError && !r.body.empty()
                      ? std::string(reinterpret_cast<const char*>(r.body.data()))
                      : std::string();
    return r.status == tims::CallStatus::kOk ? r.reply.type : int8_t{0};
  }
  int8_t set_level(Address dest, const char* level) {
    wire::ParamRecord r;
    wire::copy_text(r.name, "gdosLevel");
    r.kind = static_cast<uint8_t>(wire::ParamKind::kString);
    wire::copy_text(r.string_value, level);
    return call(dest, tims::msg::kSetParam, &r, sizeof r);
  }
  struct Rec {
    Level level;
    std::string name, text;
    uint64_t sequence;
    uint32_t dropped_before;
  };
  std::vector<Rec> records() {
    executor_->flush_log();
    std::lock_guard lock(mutex_);
    return records_;
  }
  bool saw(const std::string& name, const std::string& text_part) {
    for (const auto& r : records()) {
      if (r.name == name && r.text.find(text_part) != std::string::npos) return true;
    }
    return false;
  }

  ComponentRegistry registry_;
  std::unique_ptr<Executor> executor_;
  std::unique_ptr<tims::Mailbox> reply_box_;
  std::unique_ptr<tims::Endpoint> endpoint_;
  std::string last_error_;
  std::mutex mutex_;
  std::vector<Rec> records_;
};

constexpr Address kFlood = Address::make(0, class_ids::kGenerator, 1);
constexpr Address kGen = Address::make(0, class_ids::kGenerator, 2);

TEST_F(GdosExecutorTest, LevelFromHostFileAndAtRunTime) {
  test::Watchdog dog;
  start(R"(system: 0
lcm: false
gdos: {level: warning, stderr: never}
components:
  - name: flood
    class: LogFlood
    instance: 1
    data_task: {period_ms: 10}
    params: {gdosLevel: info}
  - name: gen
    class: Generator
    instance: 2
    data_task: {period_ms: 10}
)");
  const Component* flood = executor_->find("flood");
  const Component* gen = executor_->find("gen");
  ASSERT_NE(flood, nullptr);
  ASSERT_NE(gen, nullptr);
  EXPECT_EQ(flood->log_source().level(), Level::kInfo);   // its own
  EXPECT_EQ(gen->log_source().level(), Level::kWarning);  // the host's default
  EXPECT_EQ(flood->log_source().name(), "flood");
  // Executor events: the start.
  EXPECT_TRUE(saw("rackd", "started 2 component(s)"));
  ASSERT_EQ(call(kFlood, tims::msg::kOn), tims::msg::kOk);
  ASSERT_EQ(call(kGen, tims::msg::kOn), tims::msg::kOk);
  EXPECT_TRUE(test::eventually([&] { return saw("flood", "cycle done"); }));
  EXPECT_TRUE(saw("flood", "ON: ENABLED"));
  EXPECT_FALSE(saw("gen", "ON: ENABLED")) << "info is above gen's warning level";

  // At run time: SET_PARAM gdosLevel.
  ASSERT_EQ(set_level(kFlood, "error"), tims::msg::kOk);
  EXPECT_EQ(flood->log_source().level(), Level::kError);
  EXPECT_TRUE(saw("flood", "log level now error"));
  executor_->flush_log();
  const std::size_t before = records().size();
  ASSERT_EQ(call(kFlood, tims::msg::kOff), tims::msg::kOk);
  rt::sleep_for(50 * rt::kNsPerMs);
  std::size_t flood_after = 0;
  const auto all = records();
  for (std::size_t i = before; i < all.size(); ++i) flood_after += all[i].name == "flood" ? 1u : 0u;
  EXPECT_EQ(flood_after, 0u) << "no info records (OFF, cycle done) at level error";

  // A wrong level is refused, naming the levels; the level stays.
  EXPECT_EQ(set_level(kFlood, "verbose"), tims::msg::kError);
  EXPECT_NE(last_error_.find("print, error, warning, info, detail"), std::string::npos) << last_error_;
  EXPECT_EQ(flood->log_source().level(), Level::kError);
  ASSERT_EQ(set_level(kGen, "detail"), tims::msg::kOk);
  ASSERT_EQ(call(kGen, tims::msg::kOff), tims::msg::kOk);
  EXPECT_TRUE(saw("gen", "OFF: DISABLED"));
}

TEST_F(GdosExecutorTest, TimingTolerant_FloodDropsAndCountsWithoutStallingThePeriodicTask) {
  test::Watchdog dog;
  // 2 ms period; then 2000 records per cycle into a ring of 64: nearly all dropped.
  start(R"(system: 0
lcm: false
gdos: {level: detail, stderr: never, ring: 64, drain_ms: 5}
components:
  - name: flood
    class: LogFlood
    instance: 1
    data_task: {period_ms: 2}
    params: {burst: 0}
)");
  ASSERT_EQ(call(kFlood, tims::msg::kOn), tims::msg::kOk);
  auto& c0 = *executor_->find("flood");
  const auto& dc = dynamic_cast<const DataComponentBase&>(c0);
  // Cycles per second of the same task without and with the flood, on this machine
  // now: the flood must not slow the task down (generous tolerance: half).
  auto rate = [&] {
    const uint64_t n0 = dc.data_task_stats().summary().cycles;
    const int64_t t0 = rt::monotonic_ns();
    rt::sleep_for(400 * rt::kNsPerMs);
    const uint64_t n1 = dc.data_task_stats().summary().cycles;
    return static_cast<double>(n1 - n0) / (static_cast<double>(rt::monotonic_ns() - t0) * 1e-9);
  };
  const double quiet = rate();
  ASSERT_FALSE(c0.parameters().find("burst")->set_from_text("2000").has_value());
  const double flooded = rate();
  ASSERT_EQ(call(kFlood, tims::msg::kOff), tims::msg::kOk);
  const auto c = executor_->gdos_hub().counters();
  EXPECT_GT(quiet, 0.0);
  EXPECT_GE(flooded, 0.5 * quiet) << "cycles/s without the flood " << quiet << ", with it " << flooded;
  EXPECT_GT(c.dropped, 0u);
  // Drops are reported as a warning of the component, and the counts add up.
  uint64_t reported = 0;
  bool warning = false;
  for (const auto& r : records()) {
    if (r.name == "flood" && r.text.find("dropped: the log ring of flood data task") != std::string::npos) {
      warning = warning || r.level == Level::kWarning;
      reported += r.dropped_before;
    }
  }
  EXPECT_TRUE(warning);
  EXPECT_GT(reported, 0u);
  EXPECT_LE(reported, executor_->gdos_hub().counters().dropped);
}

TEST(GdosHostFileTest, BadGdosKeysAreReportedWithTheirPlace) {
  ComponentRegistry registry;
  components::register_builtin(registry);
  const auto r = load_host_text(R"(system: 0
lcm: false
gdos:
  level: loud
  stderr: sometimes
  ring: 1
  colour: red
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
    params: {gdosLevel: chatty}
)",
                                "bad.yaml", registry, rt::probe_capabilities());
  std::string all;
  for (const auto& e : r.errors) all += e.str() + "\n";
  EXPECT_EQ(r.errors.size(), 5u) << all;
  EXPECT_NE(all.find("bad.yaml:4:10: 'level' must be one of print, error, warning, info, detail, got 'loud'"),
            std::string::npos)
      << all;
  EXPECT_NE(all.find("bad.yaml:5:11: 'stderr' must be always, auto or never"), std::string::npos) << all;
  EXPECT_NE(all.find("bad.yaml:6:9: 'ring' = 1 is outside 2..65536"), std::string::npos) << all;
  EXPECT_NE(all.find("bad.yaml:7:3: unknown key 'colour' in gdos"), std::string::npos) << all;
  EXPECT_NE(
      all.find(
          "bad.yaml:12:25: parameter 'gdosLevel' must be one of print, error, warning, info, detail, got 'chatty'"),
      std::string::npos)
      << all;
}

// ---------------------------------------------------------------- the viewer

tims::GdosRecord make_record(const std::string& host, uint32_t source, const std::string& name, Level l,
                             const std::string& text, uint64_t seq = 1) {
  tims::GdosRecord r;
  r.host = host;
  r.pid = 42;
  r.source = source;
  r.name = name;
  r.level = static_cast<uint8_t>(l);
  r.time_ns = 1'795'304'702'722'090'458 + static_cast<int64_t>(seq);
  r.sequence = seq;
  r.text = text;
  return r;
}

TEST(GdosViewerTest, FiltersByLevelHostComponentAndText) {
  const auto warn = make_record("robot1", kLadar.raw(), "front", Level::kWarning, "range too short");
  const auto info = make_record("robot2", kGen.raw(), "gen", Level::kInfo, "ON: ENABLED");
  const auto print = make_record("robot2", kGen.raw(), "gen", Level::kPrint, "level now x");
  gdos_view::Filter f;
  EXPECT_TRUE(f.matches(warn, "front"));
  EXPECT_TRUE(f.matches(info, "gen"));
  f.max_level = Level::kWarning;
  EXPECT_TRUE(f.matches(warn, "front"));
  EXPECT_FALSE(f.matches(info, "gen"));
  f.max_level = Level::kError;
  EXPECT_TRUE(f.matches(print, "gen")) << "print always shows";
  f = {};
  f.hosts = {"robot1"};
  EXPECT_TRUE(f.matches(warn, "front"));
  EXPECT_FALSE(f.matches(info, "gen"));
  f = {};
  f.components = {"gen"};
  EXPECT_FALSE(f.matches(warn, "front"));
  EXPECT_TRUE(f.matches(info, "gen"));
  f.components = {"Ladar(0/1)"};
  EXPECT_TRUE(f.matches(warn, ""));
  f.components = {"Class0x11(0/1)"};
  EXPECT_TRUE(f.matches(warn, "")) << "another spelling of the same address";
  f.components = {"Ladar(0/2)"};
  EXPECT_FALSE(f.matches(warn, "front"));
  f = {};
  f.text = "too short";
  EXPECT_TRUE(f.matches(warn, "front"));
  EXPECT_FALSE(f.matches(info, "gen"));
}

TEST(GdosViewerTest, TextLinesHaveColoursOnlyWhenAskedAndJsonIsComplete) {
  const auto warn = make_record("robot1", kLadar.raw(), "front", Level::kWarning, "range \"short\"");
  const std::string plain = gdos_view::text_line(warn, "front", false);
  EXPECT_EQ(plain.find('\x1b'), std::string::npos);
  EXPECT_EQ(plain, "2026-11-21 23:45:02.722090 robot1     W front          range \"short\"");
  const std::string coloured = gdos_view::text_line(warn, "front", true);
  EXPECT_EQ(coloured.rfind("\x1b[33m", 0), 0u);
  EXPECT_NE(coloured.find("\x1b[0m"), std::string::npos);
  EXPECT_EQ(gdos_view::text_line(warn, "", false).find("Ladar(0/1)") != std::string::npos, true)
      << "without a name, the address";
  EXPECT_EQ(gdos_view::json_line(warn, "front"),
            "{\"host\":\"robot1\",\"pid\":42,\"time_ns\":1795304702722090459,\"time\":\"2026-11-21T23:45:02.722090Z\","
            "\"sequence\":1,\"level\":\"warning\",\"source\":\"Ladar(0/1)\",\"source_raw\":" +
                std::to_string(kLadar.raw()) +
                ",\"name\":\"front\",\"dropped_before\":0,\"text\":\"range \\\"short\\\"\"}");
}

class GdosRecordFileTest : public ::testing::Test {
 protected:
  GdosRecordFileTest()
      : path_(std::filesystem::temp_directory_path() /
              ("gdos_test_" + std::to_string(getpid()) + "_" +
               ::testing::UnitTest::GetInstance()->current_test_info()->name() + ".rec")) {}
  ~GdosRecordFileTest() override { std::filesystem::remove(path_); }
  std::vector<tims::GdosRecord> sample() {
    std::vector<tims::GdosRecord> v;
    v.push_back(make_record("robot1", kLadar.raw(), "front", Level::kWarning, "w", 1));
    v.push_back(make_record("robot2", kGen.raw(), "", Level::kDetail, std::string(70000, 'z'), 2));
    auto odd = make_record("robot1", 0xFFFFFFFFu, "üñï", Level::kPrint, std::string("nul\0inside", 10), 3);
    odd.dropped_before = 17;
    odd.time_ns = -5;
    v.push_back(odd);
    return v;
  }
  void write(const std::vector<tims::GdosRecord>& v) {
    gdos_view::RecordWriter w(path_.string(), "test");
    for (const auto& r : v) w.write(r);
    w.flush();
  }
  std::string bytes() {
    std::ifstream in(path_, std::ios::binary);
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
  }
  void put_bytes(const std::string& b) {
    std::ofstream out(path_, std::ios::binary | std::ios::trunc);
    out << b;
  }
  // Reads the whole file; returns the FileError's offset, or -1 when it read cleanly.
  long long read_all(std::vector<tims::GdosRecord>* out = nullptr, std::string* what = nullptr) {
    try {
      gdos_view::RecordReader reader(path_.string());
      tims::GdosRecord r;
      while (reader.next(r)) {
        if (out != nullptr) out->push_back(r);
      }
      return -1;
    } catch (const gdos_view::FileError& e) {
      if (what != nullptr) *what = e.what();
      return static_cast<long long>(e.offset());
    }
  }
  std::filesystem::path path_;
};

TEST_F(GdosRecordFileTest, RoundTripKeepsEveryField) {
  const auto in = sample();
  write(in);
  std::vector<tims::GdosRecord> out;
  ASSERT_EQ(read_all(&out), -1);
  ASSERT_EQ(out.size(), in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    EXPECT_EQ(out[i].host, in[i].host);
    EXPECT_EQ(out[i].pid, in[i].pid);
    EXPECT_EQ(out[i].source, in[i].source);
    EXPECT_EQ(out[i].name, in[i].name);
    EXPECT_EQ(out[i].level, in[i].level);
    EXPECT_EQ(out[i].time_ns, in[i].time_ns);
    EXPECT_EQ(out[i].sequence, in[i].sequence);
    EXPECT_EQ(out[i].dropped_before, in[i].dropped_before);
    EXPECT_EQ(out[i].text, in[i].text);
  }
  gdos_view::RecordReader reader(path_.string());
  EXPECT_EQ(reader.description(), "test");
}

TEST_F(GdosRecordFileTest, EmptyRecordingIsValid) {
  write({});
  std::vector<tims::GdosRecord> out;
  EXPECT_EQ(read_all(&out), -1);
  EXPECT_TRUE(out.empty());
}

TEST_F(GdosRecordFileTest, RejectsOtherFilesAndVersions) {
  put_bytes("hello, this is not a record file");
  std::string what;
  EXPECT_EQ(read_all(nullptr, &what), 0);
  EXPECT_NE(what.find("not a gdos record file"), std::string::npos) << what;
  write(sample());
  std::string b = bytes();
  b[8] = 9;  // version 9
  put_bytes(b);
  EXPECT_EQ(read_all(nullptr, &what), 8);
  EXPECT_NE(what.find("version 9"), std::string::npos) << what;
  put_bytes("");
  EXPECT_EQ(read_all(nullptr, &what), 0);
}

// Issue 17: `gdos --replay` of a FIFO or device waited or read for ever; a record
// length is checked against the file before its body is allocated.
TEST_F(GdosRecordFileTest, FifosDevicesAndHugeLengthsAreRefusedWithTheirOffset) {
  test::HostileDir d("gdos");
  const std::string fifo = d.fifo("fifo.gdos");
  test::HangGuard guard("RecordReader on a FIFO");
  for (const auto& [path, expect] :
       {std::pair<std::string, std::string>{fifo, fifo + ": byte offset 0: the gdos record file is a FIFO"},
        {"/dev/zero", "/dev/zero: byte offset 0: the gdos record file is a character device"},
        {d.subdir("dir"), "dir: byte offset 0: the gdos record file is a directory"}}) {
    try {
      gdos_view::RecordReader reader(path);
      ADD_FAILURE() << path << " was opened as a record file";
    } catch (const gdos_view::FileError& e) {
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
    }
  }
  write({});
  const std::size_t header = bytes().size();
  put_bytes(bytes() + std::string("\x00\x00\xf0\x00\x00\x00\x00\x00", 8) + "short");  // 15 MiB announced
  std::string what;
  EXPECT_EQ(read_all(nullptr, &what), static_cast<long long>(header));
  EXPECT_NE(what.find("truncated record (15728640 bytes announced, 5 present)"), std::string::npos) << what;
}

// gdos --record into a FIFO: opening it for writing waited for a reader, for ever.
TEST_F(GdosRecordFileTest, RecordingIntoAFifoIsRefusedNotWaitedOn) {
  test::HostileDir d("gdosrec");
  const std::string fifo = d.fifo("rec.gdos");
  test::HangGuard guard("RecordWriter on a FIFO");
  try {
    gdos_view::RecordWriter writer(fifo, "test");
    ADD_FAILURE() << fifo << " was opened to record into";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(fifo + ": cannot create the record file: a FIFO, not a regular file"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(GdosRecordFileTest, TruncatedOrCorruptRecordsNameTheirOffset) {
  write(sample());
  const std::string full = bytes();
  // Where the records start and the second one begins.
  const std::size_t header = 12u + static_cast<std::size_t>(static_cast<uint8_t>(full[10])) +
                             256u * static_cast<std::size_t>(static_cast<uint8_t>(full[11]));
  const uint32_t first_len = static_cast<uint8_t>(full[header]) | (static_cast<uint8_t>(full[header + 1]) << 8) |
                             (static_cast<uint8_t>(full[header + 2]) << 16) |
                             (static_cast<uint32_t>(static_cast<uint8_t>(full[header + 3])) << 24);
  const std::size_t second = header + 8 + first_len;
  std::string what;
  // Cut in the middle of the second record: one good record, then the error.
  put_bytes(full.substr(0, second + 20));
  std::vector<tims::GdosRecord> out;
  EXPECT_EQ(read_all(&out, &what), static_cast<long long>(second));
  EXPECT_EQ(out.size(), 1u);
  EXPECT_NE(what.find("truncated record"), std::string::npos) << what;
  EXPECT_NE(what.find("byte offset " + std::to_string(second)), std::string::npos) << what;
  // Cut inside the length field.
  put_bytes(full.substr(0, second + 3));
  EXPECT_EQ(read_all(nullptr, &what), static_cast<long long>(second));
  // A flipped byte in the first record's text: its CRC fails.
  std::string corrupt = full;
  corrupt[second - 1] ^= 0x20;
  put_bytes(corrupt);
  EXPECT_EQ(read_all(nullptr, &what), static_cast<long long>(header));
  EXPECT_NE(what.find("CRC"), std::string::npos) << what;
  // A truncated header.
  put_bytes(full.substr(0, 10));
  EXPECT_EQ(read_all(nullptr, &what), 10);
}

TEST(GdosCrcTest, MatchesTheStandardCheckValue) {
  EXPECT_EQ(gdos_view::crc32("123456789", 9), 0xCBF43926u);  // the CRC-32/IEEE check value
}

}  // namespace
}  // namespace rack
