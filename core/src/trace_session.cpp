#include "rack/core/trace_session.h"

#include <algorithm>
#include <cinttypes>
#include <climits>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <iterator>
#include <cstring>
#include <functional>
#include <map>
#include <queue>
#include <tuple>

#include "rack/core/payload_json.h"

namespace rack::trace {

using rt::trace::Event;
using rt::trace::Kind;

std::vector<std::string> split_names(const std::string& text) {
  std::vector<std::string> out;
  std::string cur;
  const auto flush = [&] {
    const auto b = cur.find_first_not_of(' ');
    const auto e = cur.find_last_not_of(' ');
    if (b != std::string::npos) out.push_back(cur.substr(b, e - b + 1));
    cur.clear();
  };
  for (const char c : text) {
    if (c == ',') flush();
    else cur += c;
  }
  flush();
  return out;
}

DecodedStart decode_start(std::span<const std::byte> body, bool swapped) {
  DecodedStart d;
  TraceStartRequest req;
  if (body.size() != sizeof req) {
    d.error = "TRACE_START body of " + std::to_string(body.size()) + " bytes, expected " + std::to_string(sizeof req);
    return d;
  }
  std::memcpy(&req, body.data(), sizeof req);
  if (std::memchr(req.names, '\0', sizeof req.names) == nullptr) {
    d.error = "TRACE_START: the names are not NUL-terminated";
    return d;
  }
  const auto raw = static_cast<uint64_t>(req.duration_ns);
  d.duration_ns = static_cast<int64_t>(swapped ? __builtin_bswap64(raw) : raw);
  d.names = split_names(req.names);
  if (d.names.size() == 1 && d.names[0] == "all") d.names.clear();
  d.ok = true;
  return d;
}

DecodedRead decode_read(std::span<const std::byte> body, bool swapped) {
  DecodedRead d;
  TraceReadRequest req;
  if (body.size() != sizeof req) {
    d.error = "TRACE_READ body of " + std::to_string(body.size()) + " bytes, expected " + std::to_string(sizeof req);
    return d;
  }
  std::memcpy(&req, body.data(), sizeof req);
  d.offset = swapped ? __builtin_bswap64(req.offset) : req.offset;
  d.ok = true;
  return d;
}

DecodedChunk decode_chunk(std::span<const std::byte> body, bool swapped, uint64_t offset, uint64_t total) {
  DecodedChunk d;
  TraceChunkHeader& h = d.header;
  const auto fail = [&](std::size_t at, const std::string& what) {
    d.error = "TRACE_READ reply, byte " + std::to_string(at) + ": " + what;
    return d;
  };
  if (body.size() < sizeof h) {
    return fail(body.size(), "the reply ends after " + std::to_string(body.size()) + " bytes, inside its " +
                                 std::to_string(sizeof h) + "-byte header");
  }
  std::memcpy(&h, body.data(), sizeof h);
  if (swapped) {
    h.state = __builtin_bswap32(h.state);
    h.length = __builtin_bswap32(h.length);
    h.offset = __builtin_bswap64(h.offset);
    h.total = __builtin_bswap64(h.total);
    h.dropped = __builtin_bswap64(h.dropped);
    h.remaining_ns = static_cast<int64_t>(__builtin_bswap64(static_cast<uint64_t>(h.remaining_ns)));
  }
  const std::size_t room = body.size() - sizeof h;
  switch (static_cast<TraceState>(h.state)) {
    case TraceState::kIdle:
    case TraceState::kRecording:
      if (h.length != 0)
        return fail(offsetof(TraceChunkHeader, length),
                    std::to_string(h.length) + " bytes of JSON before the trace is ready");
      if (room != 0) return fail(sizeof h, std::to_string(room) + " stray bytes after the header");
      if (h.remaining_ns < 0 || h.remaining_ns > kMaxTraceDurationNs) {
        return fail(offsetof(TraceChunkHeader, remaining_ns), "time left " + std::to_string(h.remaining_ns) +
                                                                  " ns is out of range (0 .. " +
                                                                  std::to_string(kMaxTraceDurationNs) + ")");
      }
      break;
    case TraceState::kReady:
      if (h.total > kMaxTraceJsonBytes) {
        return fail(offsetof(TraceChunkHeader, total), "a trace of " + std::to_string(h.total) +
                                                           " bytes is over the limit of " +
                                                           std::to_string(kMaxTraceJsonBytes));
      }
      if (total != 0 && h.total != total) {
        return fail(offsetof(TraceChunkHeader, total), "the trace's size changed from " + std::to_string(total) +
                                                           " to " + std::to_string(h.total) + " bytes");
      }
      if (h.offset != offset) {
        return fail(offsetof(TraceChunkHeader, offset),
                    "chunk at offset " + std::to_string(h.offset) + ", asked for " + std::to_string(offset));
      }
      if (h.length > kTraceChunkBytes) {
        return fail(offsetof(TraceChunkHeader, length),
                    "a chunk of " + std::to_string(h.length) + " bytes, more than the " +
                        std::to_string(kTraceChunkBytes) + " a TRACE_READ asks for");
      }
      if (h.length > room) {
        return fail(offsetof(TraceChunkHeader, length),
                    "a chunk of " + std::to_string(h.length) + " bytes, but the reply holds " + std::to_string(room));
      }
      if (h.length < room)
        return fail(sizeof h + h.length, std::to_string(room - h.length) + " stray bytes after the chunk");
      if (h.offset > h.total || h.length > h.total - h.offset) {
        return fail(offsetof(TraceChunkHeader, length), "a chunk of " + std::to_string(h.length) + " bytes at offset " +
                                                            std::to_string(h.offset) + " runs past the trace's " +
                                                            std::to_string(h.total) + " bytes");
      }
      if (h.length == 0 && h.offset < h.total) {
        return fail(offsetof(TraceChunkHeader, length), "an empty chunk at offset " + std::to_string(h.offset) +
                                                            " before the end (" + std::to_string(h.total) + " bytes)");
      }
      d.bytes = body.subspan(sizeof h, h.length);
      break;
    default:
      return fail(offsetof(TraceChunkHeader, state),
                  "unknown state " + std::to_string(h.state) + " (0 idle, 1 recording, 2 ready)");
  }
  d.ok = true;
  return d;
}

// ---------------------------------------------------------------- the JSON

namespace {

class Writer {
 public:
  Writer(std::string& out, int pid, int64_t origin) : out_(out), pid_(pid), origin_(origin) {}

  // Microseconds since the origin with nanosecond digits (Chrome's "ts" unit is us).
  void ts(const char* key, int64_t ns) {
    const int64_t d = ns - origin_;
    const int64_t a = d < 0 ? -d : d;
    char buf[64];
    std::snprintf(buf, sizeof buf, ",\"%s\":%s%" PRId64 ".%03" PRId64, key, d < 0 ? "-" : "", a / 1000, a % 1000);
    out_ += buf;
  }
  void begin(const char* ph, const std::string& name, const char* cat, int tid) {
    out_ += first_ ? "\n" : ",\n";
    first_ = false;
    out_ += "{\"ph\":\"";
    out_ += ph;
    out_ += "\",\"name\":\"" + json_escape(name) + "\"";
    // Every event carries a category: Chrome's own metadata events use "__metadata",
    // and DevTools' trace model refuses an event without one.
    out_ += std::string(",\"cat\":\"") + (cat != nullptr ? cat : "__metadata") + "\"";
    out_ += ",\"pid\":" + std::to_string(pid_) + ",\"tid\":" + std::to_string(tid);
  }
  void raw(const std::string& s) { out_ += s; }
  void end() { out_ += "}"; }

 private:
  std::string& out_;
  int pid_;
  int64_t origin_;
  bool first_ = true;
};

std::string hex_address(uint32_t a) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", a);
  return buf;
}

std::string us_text(int64_t ns) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>(ns) / 1e3);
  return buf;
}

std::string seconds_text(int64_t ns) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6f", static_cast<double>(ns) / 1e9);
  return buf;
}

// A message is known by source, destination, type and sequence number.
using MessageKey = std::tuple<uint32_t, uint32_t, uint16_t>;

}  // namespace

std::string format_chrome_trace(std::span<const TaskTrace> tasks, const TraceFormat& f) {
  const auto name_of = [&](uint32_t a) { return f.address_name ? f.address_name(a) : hex_address(a); };
  // Flows: each receive joined to the latest earlier send of the same message.
  std::map<MessageKey, std::vector<std::pair<int64_t, std::size_t>>> sends;  // key -> (time, flow slot)
  struct Flow {
    int64_t send_ns = 0;
    int send_tid = 0;
    int64_t receive_ns = 0;
    int receive_tid = 0;
    std::size_t receive_task = 0;
    bool joined = false;
  };
  std::vector<Flow> flows;
  for (const auto& t : tasks) {
    for (const auto& e : t.events) {
      if (e.kind != Kind::kSend) continue;
      sends[{e.self, e.peer, e.aux}].emplace_back(e.time_ns, flows.size());
      flows.push_back(Flow{e.time_ns, t.tid, 0, 0, false});
    }
  }
  for (auto& [key, list] : sends) std::sort(list.begin(), list.end());
  for (std::size_t ti = 0; ti < tasks.size(); ++ti) {
    const TaskTrace& t = tasks[ti];
    for (const auto& e : t.events) {
      if (e.kind != Kind::kReceive) continue;
      const auto it = sends.find({e.peer, e.self, e.aux});
      if (it == sends.end()) continue;
      // The latest send at or before the receive that no receive has taken yet.
      auto& list = it->second;
      auto pos = std::upper_bound(list.begin(), list.end(), std::make_pair(e.time_ns, SIZE_MAX));
      while (pos != list.begin()) {
        --pos;
        Flow& fl = flows[pos->second];
        if (fl.joined) break;
        fl.joined = true;
        fl.receive_ns = e.time_ns;
        fl.receive_tid = t.tid;
        fl.receive_task = ti;
        break;
      }
    }
  }

  std::string out;
  out.reserve(256 + tasks.size() * 256);
  out += "{\"displayTimeUnit\":\"ns\",\"otherData\":{\"producer\":\"rackd\",\"process\":\"" +
         json_escape(f.process_name) + "\",\"duration_s\":" + seconds_text(f.duration_ns) +
         ",\"dropped_events\":" + std::to_string(f.dropped) + "},\n\"traceEvents\":[";
  Writer w(out, f.pid, f.origin_ns);
  w.begin("M", "process_name", nullptr, 0);
  w.raw(",\"args\":{\"name\":\"" + json_escape(f.process_name) + "\"}");
  w.end();
  for (const auto& t : tasks) {
    w.begin("M", "thread_name", nullptr, t.tid);
    w.raw(",\"args\":{\"name\":\"" + json_escape(t.track) + "\"}");
    w.end();
    w.begin("M", "thread_sort_index", nullptr, t.tid);
    w.raw(",\"args\":{\"sort_index\":" + std::to_string(t.sort_index) + "}");
    w.end();
    if (t.dropped > 0) {
      w.begin("I", "events dropped (ring full)", "trace", t.tid);
      w.ts("ts", f.origin_ns);
      w.raw(",\"s\":\"t\",\"args\":{\"dropped\":" + std::to_string(t.dropped) + "}");
      w.end();
    }
  }
  // The tasks' events merged in time order (each task's are in order already): Chrome
  // DevTools binds a flow to its send and receive instants in the order of the file,
  // and draws the arrow from the first to the second.
  struct Cursor {
    std::size_t next = 0;
    int64_t start_ns = -1;
    int64_t due_ns = -1;
    int64_t wake_ns = -1;
  };
  std::vector<Cursor> cursors(tasks.size());
  using Head = std::pair<int64_t, std::size_t>;  // (time, task)
  std::priority_queue<Head, std::vector<Head>, std::greater<>> heads;
  for (std::size_t ti = 0; ti < tasks.size(); ++ti) {
    if (!tasks[ti].events.empty()) heads.emplace(tasks[ti].events.front().time_ns, ti);
  }
  while (!heads.empty()) {
    const std::size_t ti = heads.top().second;
    heads.pop();
    const TaskTrace& t = tasks[ti];
    Cursor& c = cursors[ti];
    const Event& e = t.events[c.next++];
    if (c.next < t.events.size()) heads.emplace(t.events[c.next].time_ns, ti);
    const bool data_task = t.track.size() >= 9 && t.track.compare(t.track.size() - 9, 9, "data task") == 0;
    const char* cycle_name = data_task ? "loop" : "command";
    int64_t& start_ns = c.start_ns;
    int64_t& due_ns = c.due_ns;
    int64_t& wake_ns = c.wake_ns;
    {
      switch (e.kind) {
        case Kind::kWake:
          due_ns = e.value;
          wake_ns = e.time_ns;
          w.begin("I", "wake-up", "wake", t.tid);
          w.ts("ts", e.time_ns);
          w.raw(",\"s\":\"t\",\"args\":{\"latency_us\":" + us_text(e.time_ns - e.value) + "}");
          w.end();
          break;
        case Kind::kCycleStart: start_ns = e.time_ns; break;
        case Kind::kCycleEnd: {
          if (start_ns < 0) break;     // its start came before the trace
          if (e.time_ns < start_ns) {  // out of order (a clock gone back): no negative "dur"
            start_ns = -1;
            wake_ns = -1;
            break;
          }
          w.begin("X", cycle_name, "cycle", t.tid);
          w.ts("ts", start_ns);
          w.ts("dur", f.origin_ns + (e.time_ns - start_ns));
          std::string args = ",\"args\":{\"ok\":" + std::string(e.value == 0 ? "true" : "false");
          if (wake_ns >= 0 && due_ns >= 0 && start_ns >= wake_ns) {
            args += ",\"wake_latency_us\":" + us_text(wake_ns - due_ns);
          }
          w.raw(args + "}");
          w.end();
          start_ns = -1;
          wake_ns = -1;
          break;
        }
        case Kind::kOverrun:
          w.begin("I", "overrun", "overrun", t.tid);
          w.ts("ts", e.time_ns);
          w.raw(",\"s\":\"t\",\"args\":{\"missed_periods\":" + std::to_string(e.value) + "}");
          w.end();
          break;
        case Kind::kModeSwitch:
          w.begin("I", "mode switch", "modeswitch", t.tid);
          w.ts("ts", e.time_ns);
          w.raw(",\"s\":\"t\",\"args\":{\"reports\":" + std::to_string(e.value) + "}");
          w.end();
          break;
        case Kind::kSend:
        case Kind::kReceive: {
          const bool send = e.kind == Kind::kSend;
          const int type = rt::trace::aux_type(e.aux);
          w.begin("I", std::string(send ? "send to " : "receive from ") + name_of(e.peer), "message", t.tid);
          w.ts("ts", e.time_ns);
          w.raw(",\"s\":\"t\",\"args\":{\"" + std::string(send ? "to" : "from") + "\":\"" +
                json_escape(name_of(e.peer)) + "\",\"" + std::string(send ? "from" : "to") + "\":\"" +
                json_escape(name_of(e.self)) + "\",\"type\":" + std::to_string(type) +
                ",\"seq\":" + std::to_string(rt::trace::aux_seq(e.aux)) + "}");
          w.end();
          break;
        }
        case Kind::kNone: break;
      }
    }
  }
  // Flow arrows, for the sends whose receive is in the trace too. The start binds to
  // the enclosing slice (the cycle that sent); the end to the enclosing cycle when the
  // message was taken inside one (a reply read in loop()), else to the next slice of
  // that track (a command task receives, then handles the command).
  std::vector<std::vector<std::pair<int64_t, int64_t>>> cycles(tasks.size());  // per task: (start, end) in time order
  for (std::size_t ti = 0; ti < tasks.size(); ++ti) {
    int64_t start_ns = -1;
    for (const auto& e : tasks[ti].events) {
      if (e.kind == Kind::kCycleStart) start_ns = e.time_ns;
      if (e.kind == Kind::kCycleEnd && start_ns >= 0) {
        if (e.time_ns >= start_ns) cycles[ti].emplace_back(start_ns, e.time_ns);
        start_ns = -1;
      }
    }
  }
  const auto inside_cycle = [&](std::size_t task, int64_t ns) {
    const auto& list = cycles[task];
    auto pos = std::upper_bound(list.begin(), list.end(), std::make_pair(ns, INT64_MAX));
    return pos != list.begin() && std::prev(pos)->second >= ns;
  };
  for (std::size_t i = 0; i < flows.size(); ++i) {
    const Flow& fl = flows[i];
    if (!fl.joined) continue;
    w.begin("s", "message", "message", fl.send_tid);
    w.ts("ts", fl.send_ns);
    w.raw(",\"id\":" + std::to_string(i + 1) + ",\"args\":{}");  // DevTools wants args on every event
    w.end();
    w.begin("f", "message", "message", fl.receive_tid);
    w.ts("ts", fl.receive_ns);
    w.raw(",\"id\":" + std::to_string(i + 1) + (inside_cycle(fl.receive_task, fl.receive_ns) ? ",\"bp\":\"e\"" : "") +
          ",\"args\":{}");
    w.end();
  }
  out += "\n]}\n";
  return out;
}

// ---------------------------------------------------------------- the session

void TraceSession::add_task(std::string track, std::string component, uint32_t address, rt::trace::Ring* ring) {
  Task t;
  t.trace.track = std::move(track);
  t.trace.component = std::move(component);
  t.trace.address = address;
  t.trace.sort_index = static_cast<int>(tasks_.size());
  t.ring = ring;
  tasks_.push_back(std::move(t));
}

std::string TraceSession::start(const std::vector<std::string>& names, int64_t duration_ns, int64_t now_ns,
                                uint32_t& tasks) {
  if (state_ == TraceState::kRecording) {
    return "a trace is being recorded (" + std::to_string(remaining_ns(now_ns) / 1'000'000) + " ms left)";
  }
  if (duration_ns <= 0 || duration_ns > kMaxTraceDurationNs) {
    return "duration " + std::to_string(duration_ns / 1'000'000) + " ms is out of range (1 ms .. " +
           std::to_string(kMaxTraceDurationNs / 1'000'000'000) + " s)";
  }
  const bool all = names.empty() || (names.size() == 1 && names[0] == "all");
  if (!all) {
    for (const auto& n : names) {
      const bool known = std::any_of(tasks_.begin(), tasks_.end(),
                                     [&](const Task& t) { return t.trace.component == n; });
      if (!known) return "no component named '" + n + "' on this host";
    }
  }
  json_.clear();
  json_.shrink_to_fit();
  tasks = 0;
  kept_ = 0;
  over_limit_ = 0;
  dropped_ = 0;
  scratch_.resize(4096);
  for (auto& t : tasks_) {
    t.trace.events.clear();
    t.trace.dropped = 0;
    t.selected = all || std::find(names.begin(), names.end(), t.trace.component) != names.end();
    if (!t.selected || t.ring == nullptr) continue;
    while (t.ring->drain(scratch_) > 0) {  // what is left from an earlier trace
    }
    t.dropped_at_start = t.ring->dropped();
    t.ring->set_enabled(true);
    ++tasks;
  }
  format_.origin_ns = now_ns;
  format_.duration_ns = duration_ns;
  end_ns_ = now_ns + duration_ns;
  state_ = TraceState::kRecording;
  return "";
}

void TraceSession::drain(Task& t) {
  for (;;) {
    const std::size_t n = t.ring->drain(scratch_);
    if (n == 0) break;
    const std::size_t room = kept_ < kMaxTraceEvents ? kMaxTraceEvents - kept_ : 0;
    const std::size_t keep = std::min(n, room);
    t.trace.events.insert(t.trace.events.end(), scratch_.begin(), scratch_.begin() + static_cast<std::ptrdiff_t>(keep));
    kept_ += keep;
    over_limit_ += n - keep;
    t.trace.dropped += n - keep;
  }
}

void TraceSession::poll(int64_t now_ns) {
  if (state_ != TraceState::kRecording) return;
  for (auto& t : tasks_) {
    if (t.selected && t.ring != nullptr) drain(t);
  }
  if (now_ns >= end_ns_) finish(now_ns);
}

void TraceSession::finish(int64_t now_ns) {
  if (state_ != TraceState::kRecording) return;
  for (auto& t : tasks_) {
    if (t.selected && t.ring != nullptr) t.ring->set_enabled(false);
  }
  // A hook that read the flag just before it went off may still push: the last
  // drain comes after the switch (and what comes later is cleared at the next start).
  std::vector<TaskTrace> traces;
  dropped_ = 0;
  for (auto& t : tasks_) {
    if (!t.selected || t.ring == nullptr) continue;
    drain(t);
    t.trace.dropped += t.ring->dropped() - t.dropped_at_start;
    t.trace.tid = t.ring->tid();
    dropped_ += t.trace.dropped;
    TaskTrace tr;
    tr.track = t.trace.track;
    tr.component = t.trace.component;
    tr.address = t.trace.address;
    tr.tid = t.trace.tid;
    tr.sort_index = t.trace.sort_index;
    tr.dropped = t.trace.dropped;
    tr.events = std::move(t.trace.events);
    t.trace.events.clear();
    traces.push_back(std::move(tr));
  }
  format_.duration_ns = std::min(format_.duration_ns, now_ns - format_.origin_ns);
  format_.dropped = dropped_;
  json_ = format_chrome_trace(traces, format_);
  state_ = TraceState::kReady;
}

}  // namespace rack::trace
