// The framework owns the plumbing (issue 22 item 1): no component under components/
// reads its input mailbox by hand (peek, ERROR, read, peek_end), subscribes by hand,
// or guards state shared by its command and data task with a lock of its own; it
// declares its inputs (DataComponentBase::declare_input, receive()) and hands work
// over with a Handoff<T>. Checked on the sources, with a check that the scan finds what
// it looks for. And the framework's parts that made the last conversions possible: an
// input of one of several sample types (InputOneOf), the ERRORs of inputs that do not
// fail on them (Received::errors), the inputs' malformed counts, and where a class's
// silence limit comes from (SilenceParam).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "rack/core/data_component.h"
#include "rack/core/host_config.h"
#include "monitor/monitor_types.h"
#include "rack/interfaces/demo.h"
#include "rack/interfaces/devices.h"
#include "test_support.h"

namespace rack {
namespace {

using interfaces::GeneratorData;
using interfaces::MonitorData;
using test::HostUnderTest;
using test::Stepping;
using test::Watchdog;
using tims::Address;
namespace msg = tims::msg;

// ---- the sources ------------------------------------------------------------

struct PlumbingRule {
  const char* name;
  std::regex pattern;
  const char* why;
  // Files (relative to the source tree) that may match, each with the reason.
  std::map<std::string, std::string> allowed;
};

std::vector<PlumbingRule> plumbing_rules() {
  return {
      {"input loop",
       std::regex(R"(\b(next_input|next_sample|input_silent|peek_end)\s*\(|\bpeek\s*\()"),
       "reads its input mailbox by hand (declare_input, then receive() in loop())",
       {}},
      {"subscription",
       std::regex(R"(\b(un)?subscribe\s*\(|\buse_input_mailbox\s*\()"),
       "subscribes by hand (declare_input: the framework switches the source on, subscribes before on() and "
       "unsubscribes after off())",
       {}},
      {"hand-off",
       std::regex(R"(\brt::Pi(Mutex|Lock)\b|\bstd::(mutex|lock_guard|unique_lock|scoped_lock)\b)"),
       "shares state between its tasks under a lock of its own (Handoff<T>, rack/core/handoff.h)",
       {
           {"components/evaluator/trajectory_writer.h", "the status line for rackd's main thread, not a hand-off"},
           {"components/evaluator/trajectory_writer.cpp", "the status line for rackd's main thread, not a hand-off"},
           {"components/replay/src/shared_log.cpp", "the process's table of shared logs, filled by init()"},
           {"components/modeswitch_demo/modeswitch_demo.h", "shows a lock without priority inheritance on purpose"},
           {"components/modeswitch_demo/modeswitch_demo.cpp", "shows a lock without priority inheritance on purpose"},
           {"components/modeswitch_demo/modeswitch_demo_types.h", "names that lock in its command table's text"},
       }},
  };
}

// The offences under `root` as "path:line: rule: why", and the allowed files that
// matched (so an allowance that is no longer needed is noticed).
std::vector<std::string> plumbing_offences(const std::filesystem::path& root, const std::filesystem::path& base,
                                           const std::vector<PlumbingRule>& rules,
                                           std::set<std::string>* allowed_hits = nullptr) {
  std::vector<std::string> out;
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root)) {
    const std::string ext = entry.path().extension().string();
    if (entry.is_regular_file() && (ext == ".cpp" || ext == ".h" || ext == ".hpp" || ext == ".cc")) {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  for (const auto& path : files) {
    const std::string rel = std::filesystem::relative(path, base).string();
    // Device simulators (tests' and benches' stand-ins for hardware), not components.
    if (rel.rfind("components/sims/", 0) == 0) continue;
    std::ifstream in(path);
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      if (const auto c = line.find("//"); c != std::string::npos) line.resize(c);
      for (const auto& r : rules) {
        if (!std::regex_search(line, r.pattern)) continue;
        if (r.allowed.count(rel) != 0) {
          if (allowed_hits != nullptr) allowed_hits->insert(std::string(r.name) + " " + rel);
          continue;
        }
        out.push_back(rel + ":" + std::to_string(n) + ": " + r.name + ": " + r.why);
      }
    }
  }
  return out;
}

TEST(ComponentSourceTest, NoComponentReadsItsInputsOrHandsOffByHand) {
  const std::filesystem::path base = RACK_SOURCE_DIR;
  const std::filesystem::path root = base / "components";
  ASSERT_TRUE(std::filesystem::is_directory(root)) << root;
  const auto rules = plumbing_rules();
  std::set<std::string> allowed_hits;
  const auto found = plumbing_offences(root, base, rules, &allowed_hits);
  std::string all;
  for (const auto& f : found) all += f + "\n";
  EXPECT_TRUE(found.empty()) << all;
  // Every allowance is still needed: a file that no longer matches leaves the list.
  for (const auto& r : rules) {
    for (const auto& [file, why] : r.allowed) {
      EXPECT_EQ(allowed_hits.count(std::string(r.name) + " " + file), 1u)
          << file << " is allowed a " << r.name << " (" << why << ") but has none: take it off the list";
    }
  }
}

// The rules find what they are meant to find (a check that cannot fail proves nothing).
TEST(ComponentSourceTest, ThePlumbingRulesCatchAHandWrittenLoopSubscriptionAndHandoff) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("rack-plumbing-rules-" + std::to_string(::getpid()));
  const std::filesystem::path comp = dir / "components" / "thing";
  std::filesystem::create_directories(comp);
  std::filesystem::create_directories(dir / "components" / "sims");
  std::ofstream(comp / "thing.cpp") << "HookResult Thing::on() {\n"
                                       "  return subscribe(source, 0);\n"  // 2
                                       "}\n"
                                       "HookResult Thing::loop() {\n"
                                       "  const auto p = input_mailbox().peek(kNonBlocking);\n"  // 5
                                       "  input_mailbox().peek_end();\n"                         // 6
                                       "  const Input in = next_input(h, take);\n"               // 7
                                       "  // next_input( in a comment is fine, so is unsubscribe(x)\n"
                                       "  const Received r = receive([&](const InputPort&) {});\n"
                                       "  (void)port_.receive(frame, 0);\n"
                                       "  rt::PiLock lock(mutex_);\n"  // 11
                                       "}\n"
                                       "void Thing::off() { unsubscribe(resolved(source_)); }\n";  // 13
  std::ofstream(comp / "thing.h") << "  rt::PiMutex mutex_;\n  Handoff<Move> move_;\n";            // 1
  std::ofstream(comp / "allowed.h") << "  std::mutex status_mutex_;\n";
  std::ofstream(dir / "components" / "sims" / "device_sim.cpp") << "std::lock_guard lock(m);\n";
  auto rules = plumbing_rules();
  rules[2].allowed = {{"components/thing/allowed.h", "test"}};
  std::set<std::string> allowed_hits;
  const auto found = plumbing_offences(dir / "components", dir, rules, &allowed_hits);
  std::filesystem::remove_all(dir);
  std::string all;
  for (const auto& f : found) all += f + "\n";
  ASSERT_EQ(found.size(), 7u) << all;
  EXPECT_EQ(found[0].rfind("components/thing/thing.cpp:2: subscription:", 0), 0u) << all;
  EXPECT_EQ(found[1].rfind("components/thing/thing.cpp:5: input loop:", 0), 0u) << all;
  EXPECT_EQ(found[2].rfind("components/thing/thing.cpp:6: input loop:", 0), 0u) << all;
  EXPECT_EQ(found[3].rfind("components/thing/thing.cpp:7: input loop:", 0), 0u) << all;
  EXPECT_EQ(found[4].rfind("components/thing/thing.cpp:11: hand-off:", 0), 0u) << all;
  EXPECT_EQ(found[5].rfind("components/thing/thing.cpp:13: subscription:", 0), 0u) << all;
  EXPECT_EQ(found[6].rfind("components/thing/thing.h:1: hand-off:", 0), 0u) << all;
  EXPECT_EQ(allowed_hits, std::set<std::string>{"hand-off components/thing/allowed.h"});
}

// ---- InputOneOf, Received::errors, malformed counts ------------------------------

// Publishes a MonitorData every cycle (another sample type than Generator's).
class MonitorLikeProducer final : public DataComponent<MonitorData> {
 public:
  MonitorLikeProducer() : DataComponent(DataTaskMode::kPeriodic) {}

 protected:
  HookResult loop() override {
    MonitorData d{};
    d.received = ++n_;
    publish(d, rt::host_time_ns());
    return HookResult::kOk;
  }

 private:
  uint64_t n_ = 0;
};

// Publishes a ServoDriveData (neither of the consumer's types).
class WrongSizeProducer final : public DataComponent<interfaces::ServoDriveData> {
 public:
  WrongSizeProducer() : DataComponent(DataTaskMode::kPeriodic) {}

 protected:
  HookResult loop() override {
    publish(interfaces::ServoDriveData{}, rt::host_time_ns());
    return HookResult::kOk;
  }
};

static_assert(sizeof(GeneratorData) != sizeof(MonitorData) &&
              sizeof(interfaces::ServoDriveData) != sizeof(GeneratorData) &&
              sizeof(interfaces::ServoDriveData) != sizeof(MonitorData));

// One input that takes a Generator's or a MonitorData producer's samples, and never
// fails on its source's ERROR. Publishes what it saw in a MonitorData's fields:
// received = GeneratorData samples, gaps = MonitorData samples (source_sequence: the
// newest one's `received`), latency_ns = the input's malformed count, latency_max_ns =
// its source's ERRORs (Received::errors).
class EitherConsumer final : public DataComponent<MonitorData> {
 public:
  EitherConsumer()
      : DataComponent(DataTaskMode::kTriggered),
        in_(declare_input<GeneratorData, MonitorData>(
            "source", {.doc = "a Generator or a MonitorData producer", .watched = false, .fail_on_error = false})) {}

 protected:
  HookResult loop() override {
    const Received r = receive([&](const InputPort&) {
      if (in_.holds<GeneratorData>()) {
        ++out_.received;
        out_.last_value = in_.value<GeneratorData>().value;
      } else {
        ++out_.gaps;  // counts MonitorData samples
        out_.source_sequence = in_.value<MonitorData>().received;
      }
    });
    out_.latency_ns = static_cast<int64_t>(in_.malformed());
    out_.latency_max_ns += r.errors;
    publish(out_, rt::host_time_ns());
    return HookResult::kOk;
  }
  HookResult on() override {
    out_ = MonitorData{};
    return HookResult::kOk;
  }

 private:
  InputOneOf<GeneratorData, MonitorData>& in_;
  MonitorData out_{};
};

void register_either(ComponentRegistry& r) {
  r.add({"MonitorLikeProducer", tims::classes::kFirstUser, "test: publishes MonitorData",
         [] { return std::make_unique<MonitorLikeProducer>(); }});
  r.add({"WrongSizeProducer", static_cast<uint8_t>(tims::classes::kFirstUser + 1), "test: publishes ServoDriveData",
         [] { return std::make_unique<WrongSizeProducer>(); }});
  r.add({"EitherConsumer", static_cast<uint8_t>(tims::classes::kFirstUser + 2), "test: an InputOneOf",
         [] { return std::make_unique<EitherConsumer>(); }});
}

std::string either_yaml(const std::string& source_class) {
  return R"(system: 0
lcm: false
components:
  - name: src
    class: )" +
         source_class + R"(
    data_task: {period_ms: 10, ring: 16}
  - name: either
    class: EitherConsumer
    autostart: true
    data_task: {ring: 16}
    params: {source: src}
)";
}

// The InputOneOfTest hosts are stepped (rack/core/stepper.h): waiting for a condition
// moves the virtual clock to the first instant it holds, within this much of it.
constexpr int64_t kLimit = 10 * rt::kNsPerSec;

TEST(InputOneOfTest, EachSampleIsTakenAsTheTypeOfItsSize) {
  Watchdog dog;
  for (const char* cls : {"Generator", "MonitorLikeProducer"}) {
    HostUnderTest host(either_yaml(cls), register_either, false, Stepping::kStepped);
    const Address either = host.address_of("either");
    ASSERT_EQ(host.status(either), msg::kEnabled) << host.log();
    MonitorData d{};
    wire::SampleHeader sh;
    ASSERT_TRUE(
        host.stepper().run_until([&] { return host.get_data(either, sh, d) && d.received + d.gaps >= 5; }, kLimit))
        << cls << "\n"
        << host.log();
    if (std::string(cls) == "Generator") {
      EXPECT_EQ(d.gaps, 0u) << "every Generator sample is a GeneratorData";
    } else {
      EXPECT_EQ(d.received, 0u) << "every sample of the other producer is a MonitorData";
      EXPECT_GT(d.source_sequence, 0u) << "its value() holds the sample";
    }
    EXPECT_EQ(d.latency_ns, 0) << "nothing malformed";
  }
}

TEST(InputOneOfTest, ASampleOfNoTypesSizeIsMalformedAndCountedOnTheInput) {
  Watchdog dog;
  HostUnderTest host(either_yaml("WrongSizeProducer"), register_either, false, Stepping::kStepped);
  const Address either = host.address_of("either");
  ASSERT_EQ(host.status(either), msg::kEnabled) << host.log();
  MonitorData d{};
  wire::SampleHeader sh;
  ASSERT_TRUE(host.stepper().run_until([&] { return host.get_data(either, sh, d) && d.latency_ns >= 3; }, kLimit))
      << host.log();
  EXPECT_EQ(d.received + d.gaps, 0u) << "nothing delivered";
  EXPECT_GE(host.stats(either).malformed, 3u) << "and counted in GET_STATS";
  EXPECT_EQ(host.status(either), msg::kEnabled);
}

TEST(InputOneOfTest, TheErrorOfAnInputThatDoesNotFailOnItIsCountedNotFatal) {
  Watchdog dog;
  HostUnderTest host(either_yaml("Generator"), register_either, false, Stepping::kStepped);
  const Address src = host.address_of("src");
  const Address either = host.address_of("either");
  ASSERT_EQ(host.status(either), msg::kEnabled) << host.log();
  ASSERT_EQ(host.call(src, msg::kOff).type, msg::kOk);
  MonitorData d{};
  wire::SampleHeader sh;
  ASSERT_TRUE(host.stepper().run_until([&] { return host.get_data(either, sh, d) && d.latency_max_ns == 1; }, kLimit))
      << host.log();
  EXPECT_EQ(host.status(either), msg::kEnabled) << "fail_on_error false: the consumer stays ENABLED";
}

// ---- where the silence limit comes from ------------------------------------------

template <SilenceParam Where, bool Watched>
class SilenceConsumer final : public DataComponent<MonitorData> {
 public:
  SilenceConsumer()
      : DataComponent(DataTaskMode::kTriggered),
        in_(declare_input<GeneratorData>(
            "source", {.doc = "a Generator", .watched = Watched, .silence_ms = 700.0, .silence_param = Where})) {}

 protected:
  HookResult loop() override {
    const Received r = receive([&](const InputPort&) { last_ = in_.value().value; });
    return r.failed ? HookResult::kError : HookResult::kOk;
  }

 private:
  InputOf<GeneratorData>& in_;
  double last_ = 0.0;
};

TEST(SilenceParamTest, TheClassSaysWhatTimeoutMsMeansAndAnInputMayDeclareNoSilence) {
  test::HostFileLoader loader([](ComponentRegistry& registry) {
    registry.add({"SilenceFromTimeout", tims::classes::kFirstUser, "test",
                  [] { return std::make_unique<SilenceConsumer<SilenceParam::kSilenceMs, true>>(); }});
    registry.add({"SilenceOnly", static_cast<uint8_t>(tims::classes::kFirstUser + 1), "test",
                  [] { return std::make_unique<SilenceConsumer<SilenceParam::kSilenceMsOnly, true>>(); }});
    registry.add({"NoSilence", static_cast<uint8_t>(tims::classes::kFirstUser + 2), "test",
                  [] { return std::make_unique<SilenceConsumer<SilenceParam::kNone, false>>(); }});
  });
  const std::string text = R"(system: 0
lcm: false
components:
  - name: gen
    class: Generator
    data_task: {period_ms: 10}
  - name: a
    class: SilenceFromTimeout
    data_task: {timeout_ms: 400}
    params: {source: gen}
  - name: b
    class: SilenceOnly
    data_task: {timeout_ms: 400}
    params: {source: gen}
  - name: c
    class: NoSilence
    data_task: {timeout_ms: 400}
    params: {source: gen}
)";
  const LoadResult r = loader.load(text, "silence.yaml");
  ASSERT_TRUE(r.errors.empty()) << r.errors.front().str();
  const std::string warnings = test::text_of(r.warnings);
  ASSERT_EQ(r.warnings.size(), 1u) << warnings;
  EXPECT_NE(warnings.find("component 'a': data_task.timeout_ms is now the parameter silence_ms"), std::string::npos)
      << warnings;
  std::map<std::string, const Component*> by_name;
  for (const auto& c : r.host->components) by_name[c->name()] = c.get();
  ASSERT_EQ(by_name.size(), 4u);
  EXPECT_DOUBLE_EQ(by_name["a"]->parameters().find("silence_ms")->get_float(), 400.0) << "taken from timeout_ms";
  EXPECT_DOUBLE_EQ(by_name["b"]->parameters().find("silence_ms")->get_float(), 700.0) << "its own default";
  EXPECT_EQ(by_name["b"]->settings().data_timeout_ns, 400 * rt::kNsPerMs) << "timeout_ms stays the wake-up";
  EXPECT_EQ(by_name["c"]->parameters().find("silence_ms"), nullptr) << "no silence_ms at all";

  // A watched input needs silence_ms.
  EXPECT_THROW((SilenceConsumer<SilenceParam::kNone, true>()), std::invalid_argument);
}

}  // namespace
}  // namespace rack
