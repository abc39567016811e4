#include "rack/core/gdos.h"

#include <cinttypes>
#include <cstdio>
#include <ctime>

namespace rack::gdos {

LogRing::LogRing(uint32_t slots, std::string owner) : owner_(std::move(owner)) {
  uint64_t cap = 2;
  while (cap < slots) cap <<= 1;
  capacity_ = cap;
  storage_ = std::make_unique<std::byte[]>(capacity_ * kSlotBytes);
  // Touch every page now (set-up), so the RT producer never takes a first-touch fault.
  std::memset(storage_.get(), 0, capacity_ * kSlotBytes);
}

// ---- thread binding ----

namespace {
// initial-exec: the variable lives in the executable's static TLS block, so reading
// it never calls __tls_get_addr (which may allocate for dlopen'ed modules).
thread_local LogRing* t_ring __attribute__((tls_model("initial-exec"))) = nullptr;
// Release/acquire: a thread that sees the hub's address sees the constructed hub.
std::atomic<Hub*> g_process_hub{nullptr};
}  // namespace

LogRing* detail::thread_ring() noexcept { return t_ring; }
void bind_thread_ring(LogRing* ring) noexcept { t_ring = ring; }

void Hub::set_process_hub(Hub* hub) noexcept { g_process_hub.store(hub, std::memory_order_release); }
Hub* Hub::process_hub() noexcept { return g_process_hub.load(std::memory_order_acquire); }

// ---- decoding and formatting ----

bool decode_payload(const RecordHeader& h, const std::byte* p, Value (&values)[kMaxArgs]) {
  if (h.nargs > kMaxArgs || h.bytes > kPayloadBytes) return false;
  std::size_t at = 0;
  for (std::size_t i = 0; i < h.nargs; ++i) {
    if (at + 1 > h.bytes) return false;
    const auto kind = static_cast<ArgKind>(p[at]);
    ++at;
    Value& v = values[i];
    v = Value{};
    v.kind = kind;
    auto need = [&](std::size_t n) { return at + n <= h.bytes; };
    switch (kind) {
      case ArgKind::kInt:
      case ArgKind::kPointer:
        if (!need(8)) return false;
        std::memcpy(&v.bits, p + at, 8);
        at += 8;
        break;
      case ArgKind::kDouble:
        if (!need(8)) return false;
        std::memcpy(&v.d, p + at, 8);
        at += 8;
        break;
      case ArgKind::kLongDouble:
        if (!need(sizeof(long double))) return false;
        std::memcpy(&v.ld, p + at, sizeof(long double));
        at += sizeof(long double);
        break;
      case ArgKind::kAddress: {
        if (!need(4)) return false;
        uint32_t a = 0;
        std::memcpy(&a, p + at, 4);
        v.bits = a;
        at += 4;
        break;
      }
      case ArgKind::kString: {
        if (!need(2)) return false;
        uint16_t n = 0;
        std::memcpy(&n, p + at, 2);
        at += 2;
        if (!need(n)) return false;
        v.s = std::string_view(reinterpret_cast<const char*>(p + at), n);
        at += n;
        break;
      }
      default: return false;
    }
  }
  return at == h.bytes;
}

namespace {

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wformat-nonliteral"
template <class V>
void append_one(std::string& out, const char* spec, V value) {
  char buf[512];
  const int n = std::snprintf(buf, sizeof buf, spec, value);
  if (n < 0) return;
  if (static_cast<std::size_t>(n) < sizeof buf) {
    out.append(buf, static_cast<std::size_t>(n));
    return;
  }
  // Wider than the stack buffer (a huge width): format into the string itself.
  const std::size_t old = out.size();
  out.resize(old + static_cast<std::size_t>(n) + 1);
  std::snprintf(out.data() + old, static_cast<std::size_t>(n) + 1, spec, value);
  out.resize(old + static_cast<std::size_t>(n));
}
#pragma GCC diagnostic pop

}  // namespace

bool format_values(std::string_view fmt, const Value* values, std::size_t count, std::string& out) {
  std::size_t next = 0;
  std::size_t literal = 0;
  auto fail = [&](const char* why) {
    out += " <GDOS: ";
    out += why;
    out += '>';
    return false;
  };
  auto take_int = [&](int& v) {
    if (next >= count || values[next].kind != ArgKind::kInt) return false;
    v = static_cast<int>(values[next++].bits);
    return true;
  };
  for (std::size_t i = 0; i < fmt.size(); ++i) {
    if (fmt[i] != '%') continue;
    out.append(fmt.substr(literal, i - literal));
    Conversion c;
    FormatError err = FormatError::kOk;
    if (!parse_conversion(fmt, i, c, err)) return fail("bad conversion in the format");
    i = c.end - 1;
    literal = c.end;
    if (c.conversion == '%') {
      out += '%';
      continue;
    }
    // The spec without length modifier and with '*' replaced by the values.
    int width = 0, precision = -1;
    if (c.star_width && !take_int(width)) return fail("missing * width");
    if (c.star_precision && !take_int(precision)) return fail("missing * precision");
    char spec[64];
    std::size_t k = 0;
    spec[k++] = '%';
    std::size_t j = c.begin + 1;
    while (j < c.end - 1 &&
           (fmt[j] == '-' || fmt[j] == '+' || fmt[j] == ' ' || fmt[j] == '#' || fmt[j] == '0' || fmt[j] == '\'') &&
           k < 16) {
      spec[k++] = fmt[j++];
    }
    if (c.star_width) {
      ++j;
      if (width < 0) spec[k++] = '-';  // printf: a negative * width is the '-' flag
      k += static_cast<std::size_t>(std::snprintf(spec + k, sizeof spec - k, "%d", width < 0 ? -width : width));
    } else {
      while (j < c.end - 1 && fmt[j] >= '0' && fmt[j] <= '9' && k < 40) spec[k++] = fmt[j++];
    }
    if (j < c.end - 1 && fmt[j] == '.') {
      ++j;
      if (c.star_precision) {
        ++j;
        // printf: a negative * precision is taken as if it were omitted.
        if (precision >= 0) {
          k += static_cast<std::size_t>(std::snprintf(spec + k, sizeof spec - k, ".%d", precision));
        }
      } else {
        spec[k++] = '.';
        while (j < c.end - 1 && fmt[j] >= '0' && fmt[j] <= '9' && k < 56) spec[k++] = fmt[j++];
      }
    }
    if (next >= count) return fail("missing argument");
    const Value& v = values[next++];
    const char conv = c.conversion;
    const char l0 = c.length[0], l1 = c.length[1];
    if (is_integer_conversion(conv)) {
      if (v.kind != ArgKind::kInt) return fail("argument is not an integer");
      const bool is_signed_conv = conv == 'd' || conv == 'i';
      if (conv == 'c') {
        spec[k++] = 'c';
        spec[k] = '\0';
        append_one(out, spec, static_cast<int>(v.bits));
        continue;
      }
      // printf converts the promoted argument to the type the length names.
      spec[k++] = 'l';
      spec[k++] = 'l';
      spec[k++] = conv;
      spec[k] = '\0';
      if (is_signed_conv) {
        long long x = 0;
        if (l0 == 'h' && l1 == 'h') x = static_cast<signed char>(v.bits);
        else if (l0 == 'h') x = static_cast<short>(v.bits);
        else if (l0 == 0) x = static_cast<int>(v.bits);
        else x = static_cast<long long>(v.bits);
        append_one(out, spec, x);
      } else {
        unsigned long long x = 0;
        if (l0 == 'h' && l1 == 'h') x = static_cast<unsigned char>(v.bits);
        else if (l0 == 'h') x = static_cast<unsigned short>(v.bits);
        else if (l0 == 0) x = static_cast<unsigned int>(v.bits);
        else x = v.bits;
        append_one(out, spec, x);
      }
    } else if (is_float_conversion(conv)) {
      if (l0 == 'L') {
        if (v.kind != ArgKind::kLongDouble) return fail("argument is not a long double");
        spec[k++] = 'L';
        spec[k++] = conv;
        spec[k] = '\0';
        append_one(out, spec, v.ld);
      } else {
        if (v.kind != ArgKind::kDouble) return fail("argument is not a double");
        spec[k++] = conv;
        spec[k] = '\0';
        append_one(out, spec, v.d);
      }
    } else if (conv == 's') {
      char name[48];
      std::string_view s;
      if (v.kind == ArgKind::kAddress) {
        tims::Address(static_cast<uint32_t>(v.bits)).format(name, sizeof name);
        s = name;
      } else if (v.kind == ArgKind::kString) {
        s = v.s;
      } else {
        return fail("argument is not a string");
      }
      // The view has no terminator: a precision bounds what snprintf reads. Without
      // one, the view's length is the precision; with one, the smaller of the two
      // (the user's precision applies as printf would).
      std::size_t p = s.size();
      const char* dot = static_cast<const char*>(std::memchr(spec, '.', k));
      if (dot != nullptr) {
        long given = 0;
        for (const char* q = dot + 1; q < spec + k; ++q) given = given * 10 + (*q - '0');
        if (static_cast<std::size_t>(given) < p) p = static_cast<std::size_t>(given);
        k = static_cast<std::size_t>(dot - spec);
      }
      k += static_cast<std::size_t>(std::snprintf(spec + k, sizeof spec - k, ".%zus", p));
      append_one(out, spec, s.data());
    } else if (conv == 'p') {
      if (v.kind != ArgKind::kPointer) return fail("argument is not a pointer");
      spec[k++] = 'p';
      spec[k] = '\0';
      append_one(out, spec, reinterpret_cast<const void*>(v.bits));
    }
  }
  out.append(fmt.substr(literal));
  if (next != count) return fail("more arguments than conversions");
  return true;
}

bool format_record(const RecordHeader& h, const std::byte* payload, std::string& out) {
  Value values[kMaxArgs];
  if (h.format == nullptr || !decode_payload(h, payload, values)) {
    out += "<GDOS: malformed record>";
    return false;
  }
  const bool ok = format_values(h.format, values, h.nargs, out);
  if (h.truncated != 0) out += " [cut]";
  return ok;
}

std::string format_line(const Record& r) {
  std::string line;
  append_line(r, line);
  return line;
}

void append_line(const Record& r, std::string& line) {
  const time_t secs = static_cast<time_t>(r.time_ns / rt::kNsPerSec);
  tm utc{};
  gmtime_r(&secs, &utc);
  char stamp[64];
  std::snprintf(stamp, sizeof stamp, "%04d-%02d-%02dT%02d:%02d:%02d.%06lldZ", utc.tm_year + 1900, utc.tm_mon + 1,
                utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec,
                static_cast<long long>((r.time_ns % rt::kNsPerSec) / 1000));
  char address[48];
  r.source.format(address, sizeof address);
  line += stamp;
  line += ' ';
  line += letter(r.level);
  line += ' ';
  if (!r.name.empty()) {
    line.append(r.name);
    line += ' ';
  }
  line += address;
  line += ": ";
  line.append(r.text);
  line += '\n';
}

// ---- the unbound path ----

void detail::log_unbound(const LogSource& source, Level level, const char* format, const Value* values,
                         std::size_t count) noexcept {
  try {
    std::string text;
    (void)format_values(format, values, count, text);
    if (Hub* hub = Hub::process_hub()) {
      hub->unbound_.fetch_add(1, std::memory_order_relaxed);
      hub->publish_text(level, source.address(), source.name(), std::move(text));
      return;
    }
    Record r;
    r.level = level;
    r.time_ns = rt::host_time_ns();
    r.mono_ns = rt::monotonic_ns();
    r.source = source.address();
    r.name = source.name();
    r.text = text;
    std::fputs(format_line(r).c_str(), stderr);
  } catch (...) {
    // Out of memory while logging from a non-RT thread: nothing sensible to do.
  }
}

// ---- Hub ----

Hub::Hub() = default;
Hub::~Hub() {
  Hub* self = this;
  g_process_hub.compare_exchange_strong(self, nullptr);
}

LogRing& Hub::make_ring(uint32_t slots, std::string owner) {
  auto ring = std::make_unique<LogRing>(slots, std::move(owner));
  std::lock_guard lock(rings_mutex_);
  rings_.push_back(std::move(ring));
  budget_.resize(rings_.size());
  return *rings_.back();
}

void Hub::publish_text(Level level, tims::Address source, std::string name, std::string text) {
  const int64_t now = rt::monotonic_ns();
  std::lock_guard lock(text_mutex_);
  // Bounded like the rings: a GDOS thread that cannot keep up must not let the
  // queue of preformatted text eat the heap.
  if (texts_.size() >= kMaxQueuedTexts) {
    texts_dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  texts_.push_back(Text{now, level, source, std::move(name), std::move(text)});
}

std::size_t Hub::drain(const std::function<void(const Record&)>& sink) {
  std::lock_guard rings_lock(rings_mutex_);
  // Only records stamped before the pass started are taken. Why: the scan over the
  // rings is not atomic; without a cutoff, a record committed to ring A just after
  // A was scanned could be overtaken by a later record of the same component in
  // ring B (the other task). A record stamped at or before the cutoff was committed
  // before anything stamped after it, so it is visible to this scan.
  const int64_t cutoff = rt::monotonic_ns();
  std::deque<Text>& texts = draining_;  // a member: a std::deque allocates when made
  {
    std::lock_guard lock(text_mutex_);
    if (!texts_.empty()) texts.swap(texts_);
  }
  // Records carry CLOCK_MONOTONIC; the host clock is derived once per pass.
  const int64_t offset = rt::host_time_ns() - rt::monotonic_ns();
  std::size_t n = 0;
  auto emit = [&](Record& r) {
    r.time_ns = r.mono_ns + offset;
    r.sequence = ++sequence_;
    sink(r);
    ++n;
    records_.fetch_add(1, std::memory_order_relaxed);
  };
  // Merge by time: each ring is in order (one producer, monotonic clock); picking
  // the oldest head each step keeps the two tasks of one component in call order.
  // Only what is queued now is drained: a producer that keeps writing cannot hold
  // the pass forever (each ring at most its capacity).
  // (A member, sized when rings are added: an idle pass allocates nothing.)
  std::vector<uint64_t>& budget = budget_;
  for (std::size_t i = 0; i < rings_.size(); ++i) budget[i] = rings_[i]->capacity();
  for (;;) {
    std::size_t best = SIZE_MAX;
    int64_t best_ns = INT64_MAX;
    for (std::size_t i = 0; i < rings_.size(); ++i) {
      if (budget[i] == 0) continue;
      const std::byte* p = rings_[i]->peek();
      if (p == nullptr) continue;
      RecordHeader h;
      std::memcpy(&h, p, sizeof h);
      if (h.mono_ns > cutoff) continue;  // the next pass takes it
      if (h.mono_ns < best_ns) {
        best_ns = h.mono_ns;
        best = i;
      }
    }
    const bool text_first = !texts.empty() && texts.front().mono_ns <= best_ns;
    if (best == SIZE_MAX && texts.empty()) break;
    if (text_first) {
      Text& t = texts.front();
      Record r;
      r.level = t.level;
      r.mono_ns = t.mono_ns;
      r.source = t.source;
      r.name = t.name;
      r.text = t.text;
      emit(r);
      texts.pop_front();
      continue;
    }
    LogRing& ring = *rings_[best];
    --budget[best];
    const std::byte* p = ring.peek();
    RecordHeader h;
    std::memcpy(&h, p, sizeof h);
    const std::string_view name = h.source != nullptr ? std::string_view(h.source->name()) : std::string_view();
    if (h.dropped_before > 0) {
      // Report the loss where it happened, before the record that follows it.
      scratch_ = std::to_string(h.dropped_before) + " log record(s) dropped: the log ring of " + ring.owner() + " (" +
                 std::to_string(ring.capacity()) + " records) was full";
      Record r;
      r.level = Level::kWarning;
      r.mono_ns = h.mono_ns;
      r.source = tims::Address(h.address);
      r.name = name;
      r.dropped_before = h.dropped_before;
      r.text = scratch_;
      emit(r);
    }
    scratch_.clear();
    if (!format_record(h, p + sizeof(RecordHeader), scratch_)) malformed_.fetch_add(1, std::memory_order_relaxed);
    Record r;
    r.level = h.level <= static_cast<uint8_t>(Level::kDetail) ? static_cast<Level>(h.level) : Level::kError;
    r.mono_ns = h.mono_ns;
    r.source = tims::Address(h.address);
    r.name = name;
    r.text = scratch_;
    emit(r);
    ring.pop();
  }
  // Drops with no record after them yet are reported with the ring's next record
  // (dropped_before), and counted at once in counters().
  return n;
}

HubCounters Hub::counters() const noexcept {
  HubCounters c;
  c.records = records_.load(std::memory_order_relaxed);
  c.malformed = malformed_.load(std::memory_order_relaxed);
  c.unbound = unbound_.load(std::memory_order_relaxed);
  auto* self = const_cast<Hub*>(this);
  std::lock_guard lock(self->rings_mutex_);
  for (const auto& r : rings_) c.dropped += r->dropped();
  c.dropped += texts_dropped_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace rack::gdos
