// The task timeline of one executor (README "Task timeline"): which tasks record,
// for how long, collecting their rings, and the Chrome JSON trace that Perfetto's UI
// (ui.perfetto.dev) and chrome://tracing open.
//
// How a trace leaves rackd: `rackctl trace` sends TRACE_START to the executor's trace
// mailbox (Executor(sys/host_id), local mailbox kTraceMailbox) over TiMS, so it works
// from another host; rackd's trace thread (not RT) switches the selected tasks' rings
// on, drains them every 10 ms while the trace runs, switches them off, formats the
// JSON, and serves it in chunks of kTraceChunkBytes to TRACE_READ.
//
// Real-time contract: nothing here is RT-safe; the tasks only touch their
// rt::trace::Ring (rack/rt/trace.h). Thread-safety: a TraceSession belongs to one
// thread (the executor's trace thread; tests drive it directly).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "rack/rt/trace.h"

namespace rack::trace {

// ---------------------------------------------------------------- wire (TiMS)

inline constexpr uint8_t kTraceMailbox = 2;  // local mailbox of the executor's address
inline constexpr int8_t kTraceStart = 21;    // TraceStartRequest -> OK TraceStartReply | ERROR ErrorText
inline constexpr int8_t kTraceRead = 22;     // TraceReadRequest -> OK TraceChunkHeader + bytes | ERROR
inline constexpr uint32_t kTraceChunkBytes = 32 * 1024;
inline constexpr int64_t kMaxTraceDurationNs = 60'000'000'000;  // a minute: the JSON stays below ~100 MB
inline constexpr std::size_t kMaxTraceEvents = 1'000'000;       // kept per trace; more are counted as dropped

struct TraceStartRequest {
  int64_t duration_ns = 0;  // (0, kMaxTraceDurationNs]
  char names[480] = {};     // component names separated by ',' or "all"; NUL-terminated
};
struct TraceStartReply {
  uint32_t tasks = 0;  // tasks that record
  uint32_t reserved = 0;
};
struct TraceReadRequest {
  uint64_t offset = 0;  // byte offset into the JSON
};
enum class TraceState : uint32_t { kIdle = 0, kRecording = 1, kReady = 2 };
struct TraceChunkHeader {
  uint32_t state = 0;        // TraceState
  uint32_t length = 0;       // bytes of JSON that follow this header
  uint64_t offset = 0;       // where they start
  uint64_t total = 0;        // size of the whole JSON (kReady)
  uint64_t dropped = 0;      // events lost: full rings, or over kMaxTraceEvents
  int64_t remaining_ns = 0;  // kRecording: time left
};

// Decoders of the request bodies as they arrive from the network (total: a reason,
// never a throw past them; plain functions of a byte buffer for the fuzz harnesses).
// `swapped`: the body is in the other byte order (its integers are swapped back).
struct DecodedStart {
  bool ok = false;
  std::string error;  // what is wrong, when !ok
  int64_t duration_ns = 0;
  std::vector<std::string> names;  // empty: every task
};
[[nodiscard]] DecodedStart decode_start(std::span<const std::byte> body, bool swapped);
struct DecodedRead {
  bool ok = false;
  std::string error;
  uint64_t offset = 0;
};
[[nodiscard]] DecodedRead decode_read(std::span<const std::byte> body, bool swapped);

// The most JSON a TRACE_READ peer may announce (kMaxTraceEvents events come to about
// 300 MB): a larger total is refused before anything is read.
inline constexpr uint64_t kMaxTraceJsonBytes = 1024ull * 1024 * 1024;

// Decoder of a TRACE_READ reply (OK: TraceChunkHeader + bytes) as rackctl receives it
// from the executor, or from anyone answering in its place. `offset`: the bytes read so
// far (the request's offset); `total`: the total of the earlier chunks (0: none yet).
// Refused, with what and the byte offset in the reply: a reply shorter than its header,
// an unknown state, a chunk longer than the reply or followed by stray bytes, a chunk
// longer than kTraceChunkBytes (what a TRACE_READ asks for), a chunk at another offset
// or past the announced total, a total that changes between chunks
// or is over kMaxTraceJsonBytes, an empty chunk before the end, a time left out of
// range. Total, never throws; `bytes` points into `body`.
struct DecodedChunk {
  bool ok = false;
  std::string error;
  TraceChunkHeader header;  // in this host's byte order
  std::span<const std::byte> bytes;
};
[[nodiscard]] DecodedChunk decode_chunk(std::span<const std::byte> body, bool swapped, uint64_t offset, uint64_t total);

// ---------------------------------------------------------------- the trace

// The events of one task, as the trace thread collected them.
struct TaskTrace {
  std::string track;      // "mcl data task"
  std::string component;  // "mcl"
  uint32_t address = 0;   // the component's address
  int tid = 0;            // Linux thread id (the track's tid)
  int sort_index = 0;
  std::vector<rt::trace::Event> events;  // in time order
  uint64_t dropped = 0;
};

struct TraceFormat {
  int pid = 0;
  std::string process_name;  // "rackd host 'sim'"
  int64_t origin_ns = 0;     // timestamps are microseconds since this
  int64_t duration_ns = 0;
  uint64_t dropped = 0;
  // An address's name for event names and arguments ("Ladar(0/1)"); a plain hex
  // number when not given.
  std::function<std::string(uint32_t)> address_name;
};

// The Chrome JSON trace (object form: traceEvents, displayTimeUnit, otherData):
// one track per task ("M" thread_name and thread_sort_index), "X" complete events for
// cycles (data task: "loop", command task: "command", args: wake-up latency; a cycle
// cut by the trace's start or end, or whose end is stamped before its start, is left
// out), instant events ("I", thread scope: the Trace Event Format reads "i" and "I"
// alike, Chrome DevTools' trace engine only "I") for wake-ups, overruns, mode
// switches, sends and receives, and flow events ("s"/"f") joining a send to the
// receive that took the same message (source, destination, type and sequence number)
// when both tasks were traced; each flow event has the timestamp, thread and category
// of its send or receive instant, which is what DevTools binds a flow to.
[[nodiscard]] std::string format_chrome_trace(std::span<const TaskTrace> tasks, const TraceFormat& format);

// ---------------------------------------------------------------- the session

class TraceSession {
 public:
  // Registers a task's ring (at start-up; the ring outlives the session).
  void add_task(std::string track, std::string component, uint32_t address, rt::trace::Ring* ring);

  // Starts a trace of the tasks of `names` (component names; "all" or empty: every
  // task) for duration_ns. Returns the error text (unknown name, a trace running,
  // a duration out of range), or "" and sets `tasks` to the tasks that record.
  std::string start(const std::vector<std::string>& names, int64_t duration_ns, int64_t now_ns, uint32_t& tasks);
  // Drains the rings; when the duration has passed, switches them off and formats
  // the JSON. Call every few ms while recording.
  void poll(int64_t now_ns);
  // Ends a running trace now (shutdown).
  void finish(int64_t now_ns);

  [[nodiscard]] TraceState state() const noexcept { return state_; }
  [[nodiscard]] int64_t remaining_ns(int64_t now_ns) const noexcept {
    return state_ == TraceState::kRecording && end_ns_ > now_ns ? end_ns_ - now_ns : 0;
  }
  [[nodiscard]] const std::string& json() const noexcept { return json_; }
  [[nodiscard]] uint64_t dropped() const noexcept { return dropped_; }
  TraceFormat& format() noexcept { return format_; }

 private:
  struct Task {
    TaskTrace trace;
    rt::trace::Ring* ring = nullptr;
    bool selected = false;
    uint64_t dropped_at_start = 0;
  };
  void drain(Task& t);

  std::vector<Task> tasks_;
  TraceState state_ = TraceState::kIdle;
  int64_t end_ns_ = 0;
  std::size_t kept_ = 0;
  uint64_t over_limit_ = 0;
  uint64_t dropped_ = 0;
  std::string json_;
  TraceFormat format_;
  std::vector<rt::trace::Event> scratch_;
};

// Splits "a,b, c" into names (empty parts dropped).
[[nodiscard]] std::vector<std::string> split_names(const std::string& text);

}  // namespace rack::trace
