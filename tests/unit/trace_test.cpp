// The task timeline: trace rings (ordering, drops counted, wrap-around, one producer
// and one consumer on two threads), the hooks' thread binding, and the Chrome JSON
// that TraceSession writes (parsed back by a JSON parser, not by string search).
#include <gtest/gtest.h>

#include <atomic>
#include <climits>
#include <cstring>
#include <span>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "rack/core/trace_session.h"
#include "rack/rt/trace.h"
#include "../integration/mini_json.h"

namespace rack {
namespace {

using rt::trace::Event;
using rt::trace::Kind;
using rt::trace::Ring;

Event event_at(int64_t t, Kind k = Kind::kCycleStart, int64_t value = 0) {
  Event e;
  e.time_ns = t;
  e.kind = k;
  e.value = value;
  return e;
}

TEST(TraceRingTest, CapacityIsAPowerOfTwo) {
  EXPECT_EQ(Ring(1).capacity(), 2u);
  EXPECT_EQ(Ring(100).capacity(), 128u);
  EXPECT_EQ(Ring(4096).capacity(), 4096u);
}

TEST(TraceRingTest, KeepsOrderAndCountsDropsWhenFull) {
  Ring ring(8);
  for (int i = 0; i < 12; ++i) EXPECT_EQ(ring.try_push(event_at(i)), i < 8) << i;
  EXPECT_EQ(ring.pushed(), 8u);
  EXPECT_EQ(ring.dropped(), 4u);
  std::vector<Event> out(16);
  ASSERT_EQ(ring.drain(out), 8u);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(out[static_cast<std::size_t>(i)].time_ns, i);  // oldest first, the first 8 kept
  EXPECT_EQ(ring.drain(out), 0u);
  // Room again after the drain; wrap-around keeps the order.
  for (int i = 100; i < 105; ++i) EXPECT_TRUE(ring.try_push(event_at(i)));
  std::vector<Event> two(2);
  ASSERT_EQ(ring.drain(two), 2u);  // a short drain leaves the rest
  EXPECT_EQ(two[0].time_ns, 100);
  EXPECT_EQ(two[1].time_ns, 101);
  ASSERT_EQ(ring.drain(out), 3u);
  EXPECT_EQ(out[0].time_ns, 102);
  EXPECT_EQ(out[2].time_ns, 104);
  EXPECT_EQ(ring.dropped(), 4u);
}

TEST(TraceRingTest, HooksRecordOnlyIntoTheBoundRingWhileEnabled) {
  Ring ring(16);
  rt::trace::record(Kind::kWake, 1);  // no ring bound: nothing, no crash
  rt::trace::bind_thread_ring(&ring);
  EXPECT_GT(ring.tid(), 0);
  EXPECT_FALSE(rt::trace::active());
  rt::trace::record(Kind::kWake, 2);  // bound but off
  EXPECT_EQ(ring.pushed(), 0u);
  ring.set_enabled(true);
  EXPECT_TRUE(rt::trace::active());
  rt::trace::record(Kind::kSend, 0, 0x01020304u, rt::trace::message_aux(-7, 9), 0x0A0B0C0Du);
  rt::trace::record_at(12345, Kind::kOverrun, 3);
  std::thread other([] { rt::trace::record(Kind::kWake, 4); });  // another thread: not bound
  other.join();
  rt::trace::bind_thread_ring(nullptr);
  rt::trace::record(Kind::kWake, 5);
  std::vector<Event> out(8);
  ASSERT_EQ(ring.drain(out), 2u);
  EXPECT_EQ(out[0].kind, Kind::kSend);
  EXPECT_EQ(out[0].peer, 0x01020304u);
  EXPECT_EQ(out[0].self, 0x0A0B0C0Du);
  EXPECT_EQ(rt::trace::aux_type(out[0].aux), -7);
  EXPECT_EQ(rt::trace::aux_seq(out[0].aux), 9);
  EXPECT_GT(out[0].time_ns, 0);
  EXPECT_EQ(out[1].kind, Kind::kOverrun);
  EXPECT_EQ(out[1].time_ns, 12345);
  EXPECT_EQ(out[1].value, 3);
}

TEST(TraceRingTest, ProducerAndConsumerOnTwoThreadsLoseNothingButTheCountedDrops) {
  // Watchdog: the producer ends after kEvents pushes; the consumer after it ended and
  // the ring is empty.
  constexpr int64_t kEvents = 200'000;
  Ring ring(256);
  std::atomic<bool> done{false};
  std::vector<int64_t> seen;
  seen.reserve(static_cast<std::size_t>(kEvents));
  std::thread consumer([&] {
    std::vector<Event> out(64);
    for (;;) {
      const bool finished = done.load(std::memory_order_acquire);
      const std::size_t n = ring.drain(out);
      for (std::size_t i = 0; i < n; ++i) seen.push_back(out[i].time_ns);
      if (n == 0 && finished) break;
      if (n == 0) std::this_thread::yield();
    }
  });
  for (int64_t i = 0; i < kEvents; ++i) (void)ring.try_push(event_at(i));
  done.store(true, std::memory_order_release);
  consumer.join();
  EXPECT_EQ(seen.size() + ring.dropped(), static_cast<std::size_t>(kEvents));
  EXPECT_EQ(ring.pushed(), seen.size());
  for (std::size_t i = 1; i < seen.size(); ++i) ASSERT_LT(seen[i - 1], seen[i]) << "out of order at " << i;
}

// ---------------------------------------------------------------- the JSON

const test::Json* find_event(const test::Json& events, const std::string& ph, const std::string& name) {
  for (const auto& e : events.array) {
    if (e.at("ph").string == ph && e.at("name").string == name) return &e;
  }
  return nullptr;
}

TEST(TraceSessionTest, WritesTracksCyclesInstantsAndFlowsAsChromeJson) {
  Ring producer(64), consumer(64);
  trace::TraceSession session;
  session.add_task("ladar data task", "ladar", 0x00010100u, &producer);
  session.add_task("mcl data task", "mcl", 0x00020100u, &consumer);
  session.format().pid = 42;
  session.format().process_name = "rackd host 'unit'";
  session.format().address_name = [](uint32_t a) { return a == 0x00020101u ? std::string("mcl#1") : std::string("x"); };
  uint32_t tasks = 0;
  ASSERT_EQ(session.start({"bogus"}, 1'000'000, 0, tasks), "no component named 'bogus' on this host");
  ASSERT_EQ(session.start({"all"}, 0, 0, tasks).find("out of range") != std::string::npos, true);
  ASSERT_EQ(session.start({}, 1'000'000, 1'000, tasks), "");
  EXPECT_EQ(tasks, 2u);
  EXPECT_TRUE(producer.enabled());
  EXPECT_EQ(session.state(), trace::TraceState::kRecording);
  EXPECT_NE(session.start({}, 1'000'000, 2'000, tasks), "") << "a second trace while one runs";
  // The producer wakes 20 us late, sends to mcl's data mailbox inside its cycle,
  // overruns; mcl takes the message and runs its cycle.
  Event send = event_at(5'000, Kind::kSend);
  send.peer = 0x00020101u;
  send.self = 0x00010100u;
  send.aux = rt::trace::message_aux(-6, 17);
  Event receive = event_at(6'000, Kind::kReceive);
  receive.peer = 0x00010100u;
  receive.self = 0x00020101u;
  receive.aux = send.aux;
  for (const Event& e : {event_at(3'020, Kind::kWake, 3'000), event_at(4'000, Kind::kCycleStart), send,
                         event_at(9'000, Kind::kCycleEnd), event_at(9'500, Kind::kOverrun, 2)}) {
    ASSERT_TRUE(producer.try_push(e));
  }
  for (const Event& e : {receive, event_at(6'500, Kind::kCycleStart), event_at(8'000, Kind::kModeSwitch, 1),
                         event_at(8'500, Kind::kCycleEnd, 1)}) {
    ASSERT_TRUE(consumer.try_push(e));
  }
  session.poll(500'000);
  EXPECT_EQ(session.state(), trace::TraceState::kRecording);
  session.poll(1'001'000);
  ASSERT_EQ(session.state(), trace::TraceState::kReady);
  EXPECT_FALSE(producer.enabled()) << "switched off at the end";

  const auto doc = test::parse_json(session.json());
  ASSERT_TRUE(doc.has_value()) << session.json();
  const test::Json& events = doc->at("traceEvents");
  EXPECT_EQ(doc->at("otherData").at("dropped_events").number, 0);
  std::set<std::string> tracks;
  for (const auto& e : events.array) {
    EXPECT_EQ(e.at("pid").number, 42);
    if (e.at("ph").string == "M" && e.at("name").string == "thread_name") tracks.insert(e.at("args").at("name").string);
  }
  EXPECT_EQ(tracks, (std::set<std::string>{"ladar data task", "mcl data task"}));
  // The events are written in time order across the tracks: mcl's cycle (ends at
  // 8.5 us) before the ladar's (ends at 9 us); the ladar's is the one that woke up.
  const test::Json* loop = nullptr;
  int loops = 0;
  for (const auto& e : events.array) {
    if (e.at("ph").string != "X" || e.at("name").string != "loop") continue;
    ++loops;
    if (e.at("args").at("wake_latency_us").is_number()) loop = &e;
  }
  EXPECT_EQ(loops, 2);
  ASSERT_NE(loop, nullptr);
  EXPECT_DOUBLE_EQ(loop->at("ts").number, 3.0);  // us since the trace start (1000 ns)
  EXPECT_DOUBLE_EQ(loop->at("dur").number, 5.0);
  EXPECT_DOUBLE_EQ(loop->at("args").at("wake_latency_us").number, 0.02);
  const test::Json* overrun = find_event(events, "I", "overrun");
  ASSERT_NE(overrun, nullptr);
  EXPECT_EQ(overrun->at("args").at("missed_periods").number, 2);
  ASSERT_NE(find_event(events, "I", "mode switch"), nullptr);
  const test::Json* sent = find_event(events, "I", "send to mcl#1");
  ASSERT_NE(sent, nullptr);
  EXPECT_EQ(sent->at("args").at("seq").number, 17);
  EXPECT_EQ(sent->at("args").at("type").number, -6);
  const test::Json* s = find_event(events, "s", "message");
  const test::Json* f = find_event(events, "f", "message");
  ASSERT_NE(s, nullptr);
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(s->at("id").number, f->at("id").number);
  EXPECT_DOUBLE_EQ(s->at("ts").number, 4.0);
  EXPECT_DOUBLE_EQ(f->at("ts").number, 5.0);
  EXPECT_EQ(f->get("bp"), nullptr) << "taken before mcl's cycle: binds to the next slice";

  // A new trace starts empty (nothing of the last one is served twice).
  ASSERT_EQ(session.start({"mcl"}, 1'000, 2'000'000, tasks), "");
  EXPECT_EQ(tasks, 1u);
  EXPECT_FALSE(producer.enabled());
  session.poll(3'000'000);
  const auto doc2 = test::parse_json(session.json());
  ASSERT_TRUE(doc2.has_value());
  EXPECT_EQ(find_event(doc2->at("traceEvents"), "X", "loop"), nullptr);
}

TEST(TraceSessionTest, CountsTheEventsAFullRingDropped) {
  Ring ring(4);
  trace::TraceSession session;
  session.add_task("a command task", "a", 0x00010100u, &ring);
  uint32_t tasks = 0;
  ASSERT_EQ(session.start({"a"}, 1'000, 0, tasks), "");
  for (int i = 0; i < 10; ++i) (void)ring.try_push(event_at(i));
  session.poll(2'000);
  EXPECT_EQ(session.dropped(), 6u);
  const auto doc = test::parse_json(session.json());
  ASSERT_TRUE(doc.has_value());
  EXPECT_EQ(doc->at("otherData").at("dropped_events").number, 6);
  const test::Json* note = find_event(doc->at("traceEvents"), "I", "events dropped (ring full)");
  ASSERT_NE(note, nullptr);
  EXPECT_EQ(note->at("args").at("dropped").number, 6);
}

std::span<const std::byte> as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::byte*>(s.data()), s.size()};
}

// A TRACE_READ reply as rackctl reads it: from rackd, or from a broken peer.
TEST(TraceSessionTest, DecodesReadRepliesOrSaysWhatIsWrongAndWhere) {
  const std::string json = R"({"traceEvents":[]})";
  const auto reply = [&](trace::TraceChunkHeader h, std::size_t from, std::size_t n) {
    std::string b(reinterpret_cast<const char*>(&h), sizeof h);  // the bytes of a reply
    b.append(json, from, n);
    return b;
  };
  trace::TraceChunkHeader h;
  h.state = static_cast<uint32_t>(trace::TraceState::kReady);
  h.total = json.size();
  h.length = 8;
  auto b = reply(h, 0, 8);
  trace::DecodedChunk d = trace::decode_chunk(as_bytes(b), false, 0, 0);
  ASSERT_TRUE(d.ok) << d.error;
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(d.bytes.data()), d.bytes.size()), json.substr(0, 8));
  // The rest, at offset 8, the total known from the first chunk.
  h.offset = 8;
  h.length = static_cast<uint32_t>(json.size() - 8);
  b = reply(h, 8, json.size() - 8);
  d = trace::decode_chunk(as_bytes(b), false, 8, json.size());
  ASSERT_TRUE(d.ok) << d.error;
  // The other byte order.
  trace::TraceChunkHeader sw = h;
  sw.state = __builtin_bswap32(h.state);
  sw.length = __builtin_bswap32(h.length);
  sw.offset = __builtin_bswap64(h.offset);
  sw.total = __builtin_bswap64(h.total);
  b = reply(sw, 8, json.size() - 8);
  d = trace::decode_chunk(as_bytes(b), true, 8, json.size());
  ASSERT_TRUE(d.ok) << d.error;
  EXPECT_EQ(d.header.length, json.size() - 8);

  const auto refused = [&](const std::string& body, uint64_t offset, uint64_t total, const char* what,
                           const std::string& where) {
    const trace::DecodedChunk r = trace::decode_chunk(as_bytes(body), false, offset, total);
    EXPECT_FALSE(r.ok) << what;
    EXPECT_NE(r.error.find(what), std::string::npos) << r.error;
    EXPECT_NE(r.error.find(where), std::string::npos) << r.error;
  };
  // Truncated: inside the header, and a chunk longer than the reply.
  b = reply(h, 8, json.size() - 8);
  refused(b.substr(0, 20), 8, 0, "inside its 40-byte header", "byte 20");
  refused(b.substr(0, b.size() - 1), 8, 0, "but the reply holds", "byte 4");
  // Wrong counts: stray bytes, a chunk past the total, a total that changed.
  auto longer = b;
  longer += '\0';
  refused(longer, 8, 0, "1 stray bytes", "byte " + std::to_string(b.size()));
  trace::TraceChunkHeader past = h;
  past.total = 10;
  refused(reply(past, 8, json.size() - 8), 8, 0, "runs past the trace's 10 bytes", "byte 4");
  refused(b, 8, 999, "changed from 999", "byte 16");
  // Huge counts: a total over the limit, a time left beyond any trace.
  trace::TraceChunkHeader huge = h;
  huge.total = uint64_t{1} << 62;
  refused(reply(huge, 8, json.size() - 8), 8, 0, "over the limit", "byte 16");
  trace::TraceChunkHeader rec;
  rec.state = static_cast<uint32_t>(trace::TraceState::kRecording);
  rec.remaining_ns = INT64_MAX;
  refused(reply(rec, 0, 0), 0, 0, "out of range", "byte 32");
  rec.remaining_ns = 5;
  rec.length = 3;
  refused(reply(rec, 0, 3), 0, 0, "before the trace is ready", "byte 4");
  // A chunk longer than a TRACE_READ asks for: a peer sends no more than that at once.
  trace::TraceChunkHeader big = h;
  big.length = trace::kTraceChunkBytes + 1;
  big.total = 8 + big.length;
  std::string bigger(reinterpret_cast<const char*>(&big), sizeof big);
  bigger.append(big.length, 'x');
  refused(bigger, 8, 0, "more than the 32768 a TRACE_READ asks for", "byte 4");
  // Out of order: a chunk at another offset than asked for, an empty chunk before the end.
  refused(b, 0, 0, "chunk at offset 8, asked for 0", "byte 8");
  trace::TraceChunkHeader empty = h;
  empty.length = 0;
  refused(reply(empty, 0, 0), 8, 0, "an empty chunk at offset 8", "byte 4");
  trace::TraceChunkHeader odd = h;
  odd.state = 7;
  refused(reply(odd, 0, 0), 8, 0, "unknown state 7", "byte 0");
}

TEST(TraceSessionTest, DecodesRequestsFromTheNetworkOrSaysWhatIsWrong) {
  trace::TraceStartRequest req;
  req.duration_ns = 2'000'000'000;
  std::memcpy(req.names, "mcl, ladar", 10);
  const auto bytes = [](const auto& v) {
    return std::span<const std::byte>(reinterpret_cast<const std::byte*>(&v), sizeof v);
  };
  trace::DecodedStart d = trace::decode_start(bytes(req), false);
  ASSERT_TRUE(d.ok) << d.error;
  EXPECT_EQ(d.duration_ns, 2'000'000'000);
  EXPECT_EQ(d.names, (std::vector<std::string>{"mcl", "ladar"}));
  // The other byte order: the integer is swapped back.
  trace::TraceStartRequest big = req;
  big.duration_ns = static_cast<int64_t>(__builtin_bswap64(static_cast<uint64_t>(req.duration_ns)));
  d = trace::decode_start(bytes(big), true);
  ASSERT_TRUE(d.ok);
  EXPECT_EQ(d.duration_ns, 2'000'000'000);
  // "all" is every task.
  std::memcpy(req.names, "all", 4);
  d = trace::decode_start(bytes(req), false);
  ASSERT_TRUE(d.ok);
  EXPECT_TRUE(d.names.empty());
  // Short, long, unterminated.
  d = trace::decode_start(bytes(req).first(10), false);
  EXPECT_FALSE(d.ok);
  EXPECT_NE(d.error.find("10 bytes"), std::string::npos) << d.error;
  std::memset(req.names, 'x', sizeof req.names);
  d = trace::decode_start(bytes(req), false);
  EXPECT_FALSE(d.ok);
  EXPECT_NE(d.error.find("NUL"), std::string::npos) << d.error;
  trace::TraceReadRequest rr;
  rr.offset = 65536;
  trace::DecodedRead r = trace::decode_read(bytes(rr), false);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.offset, 65536u);
  r = trace::decode_read(bytes(rr).first(3), false);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.error.find("3 bytes"), std::string::npos) << r.error;
}

TEST(TraceSessionTest, SplitsNameLists) {
  EXPECT_EQ(trace::split_names("mcl, ladar,,pilot "), (std::vector<std::string>{"mcl", "ladar", "pilot"}));
  EXPECT_TRUE(trace::split_names("").empty());
}

}  // namespace
}  // namespace rack
