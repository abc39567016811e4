// No allocation after initialisation on the message path.
//
// This binary replaces the global allocator (operator new/delete and glibc's malloc
// family, forwarding to glibc's __libc_* entry points) with versions that count every
// allocation made, by any thread, while counting is switched on. Each test sets up
// and warms up its path, then switches counting on around the measured loop only:
// the count must stay 0. Alone in its binary because the replacement is global.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <new>
#include <string>
#include <thread>

#include "rack/interfaces/demo.h"
#include "test_support.h"

// ---- the counting allocator ----------------------------------------------------

namespace {
// Relaxed: a flag and a statistic; the measured loop is bracketed on one thread and
// the count is read after the threads involved have synchronised through mailboxes.
std::atomic<bool> g_counting{false};
std::atomic<uint64_t> g_allocations{0};
void note_allocation() noexcept {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* ptr, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* ptr);

void* malloc(std::size_t size) noexcept {
  note_allocation();
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  note_allocation();
  return __libc_calloc(count, size);
}
void* realloc(void* ptr, std::size_t size) noexcept {
  note_allocation();
  return __libc_realloc(ptr, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  note_allocation();
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  note_allocation();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  note_allocation();
  if (alignment < sizeof(void*) || (alignment & (alignment - 1)) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void free(void* ptr) noexcept { __libc_free(ptr); }
}  // extern "C"

namespace {
void* counted_new(std::size_t size) {
  note_allocation();
  if (void* p = __libc_malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* counted_new_aligned(std::size_t size, std::align_val_t align) {
  note_allocation();
  if (void* p = __libc_memalign(static_cast<std::size_t>(align), size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
}  // namespace

void* operator new(std::size_t size) { return counted_new(size); }
void* operator new[](std::size_t size) { return counted_new(size); }
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  note_allocation();
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  note_allocation();
  return __libc_malloc(size == 0 ? 1 : size);
}
void* operator new(std::size_t size, std::align_val_t align) { return counted_new_aligned(size, align); }
void* operator new[](std::size_t size, std::align_val_t align) { return counted_new_aligned(size, align); }
void operator delete(void* p) noexcept { __libc_free(p); }
void operator delete[](void* p) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t) noexcept { __libc_free(p); }
void operator delete(void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete[](void* p, const std::nothrow_t&) noexcept { __libc_free(p); }
void operator delete(void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { __libc_free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { __libc_free(p); }

// ---- tests ---------------------------------------------------------------------

namespace rack {
namespace {

using tims::Address;
using tims::ConstBuffer;
using tims::Mailbox;
using tims::RecvStatus;
using tims::SendStatus;
namespace msg = tims::msg;

// Counts allocations (all threads) from construction to stop().
class AllocationCounter {
 public:
  AllocationCounter() {
    g_allocations.store(0, std::memory_order_relaxed);
    g_counting.store(true, std::memory_order_seq_cst);
  }
  ~AllocationCounter() { g_counting.store(false, std::memory_order_seq_cst); }
  AllocationCounter(const AllocationCounter&) = delete;
  AllocationCounter& operator=(const AllocationCounter&) = delete;
  uint64_t stop() {
    g_counting.store(false, std::memory_order_seq_cst);
    return g_allocations.load(std::memory_order_relaxed);
  }
};

void* volatile g_sink = nullptr;  // keeps the compiler from eliding test allocations

class NoAllocationTest : public ::testing::Test {
 protected:
  static constexpr int kWarmUp = 20;
  static constexpr int kRounds = 500;
  static constexpr Address kA = Address::make(0, tims::classes::kTool, 1, 1);
  static constexpr Address kB = Address::make(0, tims::classes::kTool, 2, 1);
};

TEST_F(NoAllocationTest, CounterSeesAllocations) {
  // The check must be able to fail: every kind of allocation is seen.
  {
    AllocationCounter c;
    g_sink = std::malloc(16);
    std::free(g_sink);
    EXPECT_EQ(c.stop(), 1u);
  }
  {
    AllocationCounter c;
    g_sink = new int(3);
    delete static_cast<int*>(g_sink);
    EXPECT_EQ(c.stop(), 1u);
  }
  {
    AllocationCounter c;
    std::string s(200, 'x');  // allocates inside libstdc++
    g_sink = s.data();
    EXPECT_GE(c.stop(), 1u);
  }
  {
    AllocationCounter c;
    std::thread t([] { g_sink = std::malloc(8); });
    t.join();
    std::free(g_sink);
    EXPECT_GE(c.stop(), 2u);  // the thread's start and its malloc
  }
  {
    AllocationCounter c;
    c.stop();
    g_sink = std::malloc(8);  // after stop: not counted
    std::free(g_sink);
    EXPECT_EQ(g_allocations.load(), 0u);
  }
}

TEST_F(NoAllocationTest, MailboxSendReceivePeek) {
  Mailbox m(kA, 8, 256);
  alignas(8) std::array<std::byte, 256> buf{};
  const test::Tag tag{1, 0};
  auto round = [&](int i) {
    const auto h = test::tag_header(kA, kB, static_cast<uint8_t>(i % 4));
    if (!delivered(m.try_send(h, {tims::buffer_of(tag)}))) return false;
    if (!delivered(m.try_send(h, {tims::buffer_of(tag)}))) return false;
    if (m.receive(buf, Mailbox::kNonBlocking).status != RecvStatus::kOk) return false;
    const auto p = m.peek(Mailbox::kNonBlocking);
    if (p.status != RecvStatus::kOk) return false;
    m.peek_end();
    // Full mailbox: drop policy and refusals allocate nothing either.
    for (int k = 0; k < 10; ++k) (void)m.try_send(h, {tims::buffer_of(tag)});
    while (m.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk) {
    }
    return m.receive(buf, 1000).status == RecvStatus::kTimeout;  // timed wait path
  };
  for (int i = 0; i < kWarmUp; ++i) ASSERT_TRUE(round(i));
  int failures = 0;
  AllocationCounter counter;
  for (int i = 0; i < kRounds; ++i) failures += round(i) ? 0 : 1;
  const uint64_t allocations = counter.stop();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(allocations, 0u);
}

TEST_F(NoAllocationTest, RouterSend) {
  tims::Router router(0);
  Mailbox a(kA, 8, 256), b(kB, 8, 256);
  router.add(a);
  router.add(b);
  alignas(8) std::array<std::byte, 256> buf{};
  const test::Tag tag{2, 0};
  auto round = [&] {
    if (router.send(test::tag_header(kB, kA, 1), {tims::buffer_of(tag)}) != SendStatus::kOk) return false;
    if (b.receive(buf, Mailbox::kNonBlocking).status != RecvStatus::kOk) return false;
    // A request to nobody: answered NOT_AVAILABLE into a.
    const auto req = tims::make_header(Address::make(0, tims::classes::kLadar, 9), kA, msg::kOn, 1, 1, 0);
    if (router.send(req, std::span<const ConstBuffer>{}) != SendStatus::kNotAvailable) return false;
    return a.receive(buf, Mailbox::kNonBlocking).status == RecvStatus::kOk;
  };
  for (int i = 0; i < kWarmUp; ++i) ASSERT_TRUE(round());
  int failures = 0;
  AllocationCounter counter;
  for (int i = 0; i < kRounds; ++i) failures += round() ? 0 : 1;
  const uint64_t allocations = counter.stop();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(allocations, 0u);
  router.remove(kA);
  router.remove(kB);
}

TEST_F(NoAllocationTest, EndpointCallRoundTrip) {
  test::Watchdog dog;
  tims::Router router(0);
  Mailbox client_box(kA, 8, 256), server_box(kB, 8, 256);
  router.add(client_box);
  router.add(server_box);
  std::atomic<bool> stop{false};
  std::thread server([&] {
    tims::Endpoint ep(router, server_box, 5);
    alignas(8) std::array<std::byte, 256> b{};
    while (!stop.load(std::memory_order_acquire)) {
      const auto r = server_box.receive(b, 10 * rt::kNsPerMs);
      if (r.status != RecvStatus::kOk) continue;
      const ConstBuffer body{b.data() + sizeof(tims::MessageHeader), r.length - sizeof(tims::MessageHeader)};
      (void)ep.reply(r.header, msg::kOk, std::span<const ConstBuffer>(&body, 1));
    }
  });
  tims::Endpoint client(router, client_box, 5);
  alignas(8) std::array<std::byte, 256> buf{};
  const uint64_t word = 42;
  auto round = [&] {
    const auto r = client.call(kB, 21, word, buf, test::kCallTimeoutNs);
    return r.ok() && r.body.size() == sizeof word;
  };
  for (int i = 0; i < kWarmUp; ++i) ASSERT_TRUE(round());
  int failures = 0;
  {
    AllocationCounter counter;
    for (int i = 0; i < kRounds; ++i) failures += round() ? 0 : 1;
    const uint64_t allocations = counter.stop();
    EXPECT_EQ(allocations, 0u);
  }
  stop.store(true, std::memory_order_release);
  server.join();
  EXPECT_EQ(failures, 0);
  router.remove(kA);
  router.remove(kB);
}

TEST_F(NoAllocationTest, RpcToARunningExecutorComponent) {
  test::Watchdog dog;
  test::HostUnderTest host(R"(system: 0
lcm: false
components:
  - name: probe
    class: Probe
    instance: 1
    data_task: {period_ms: 5, ring: 64}
  - name: gen
    class: Generator
    instance: 1
    data_task: {period_ms: 5}
)");
  const Address probe = host.address_of("probe");
  const Address gen = host.address_of("gen");
  ASSERT_EQ(host.call(probe, msg::kOn).type, msg::kOk);
  ASSERT_EQ(host.call(gen, msg::kOn).type, msg::kOk);
  // A stream of generator samples into the tool's data mailbox: the producer's
  // publish path runs during the measurement too.
  wire::ContDataRequest cont;
  cont.mailbox = host.data_mailbox().address().raw();
  ASSERT_EQ(host.call_with(gen, msg::kGetContData, cont).type, msg::kContData);
  ASSERT_TRUE(test::eventually([&] {
    wire::SampleHeader h;
    interfaces::ProbeData d;
    return host.get_data(probe, h, d);
  }));
  // The generator too: GET_DATA on an empty ring is (rightly) an ERROR.
  ASSERT_TRUE(test::eventually([&] {
    wire::SampleHeader h;
    interfaces::GeneratorData d;
    return host.get_data(gen, h, d);
  }));

  tims::Endpoint& ep = host.endpoint();
  alignas(8) std::array<std::byte, 4096> buf{};
  alignas(8) std::array<std::byte, 1024> data{};
  wire::ParamName pname;
  wire::copy_text(pname.name, "label");
  uint64_t bad = 0, streamed = 0;
  auto round = [&] {
    auto r = ep.call(probe, msg::kGetStatus, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kEnabled ? 0 : 1;
    r = ep.call(probe, msg::kGetData, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kData ? 0 : 1;
    r = ep.call(gen, msg::kGetData, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kData ? 0 : 1;
    r = ep.call(probe, msg::kGetParam, pname, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kParam ? 0 : 1;
    r = ep.call(probe, msg::kGetStats, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kStats ? 0 : 1;
    r = ep.call(Address::make(0, tims::classes::kLadar, 7), msg::kGetStatus, buf, test::kCallTimeoutNs);
    bad += r.status == tims::CallStatus::kOk && r.reply.type == msg::kNotAvailable ? 0 : 1;
    while (host.data_mailbox().receive(data, Mailbox::kNonBlocking).status == RecvStatus::kOk) ++streamed;
  };
  for (int i = 0; i < kWarmUp; ++i) round();
  ASSERT_EQ(bad, 0u);
  streamed = 0;
  uint64_t allocations = 0;
  {
    // At least 200 rounds, and on until a few streamed samples arrived (the producer's
    // period is 5 ms; 200 rounds can be quicker than that). Bounded by the watchdog.
    AllocationCounter counter;
    for (int i = 0; i < 200 || (streamed < 3 && i < 200000); ++i) round();
    allocations = counter.stop();
  }
  EXPECT_EQ(bad, 0u);
  EXPECT_GT(streamed, 0u) << "the producer published during the measurement";
  EXPECT_EQ(allocations, 0u);
}

}  // namespace
}  // namespace rack
