// GDOS: RACK's distributed log service, real-time safe.
//
// A log call in an RT task does not format, allocate, lock or make a system call: it
// checks the source's level (one relaxed atomic load), reads CLOCK_MONOTONIC (vDSO),
// and copies the format pointer and the raw arguments (strings copied, bounded) into
// the calling task's preallocated single-producer ring. A full ring drops the record
// and counts it; the next record that fits carries the count. A non-RT thread per
// host (the executor's GDOS thread, Hub::drain) formats the records with snprintf,
// one conversion at a time, and hands them to the sinks: rackd's stderr and LCM
// (rack/tims/gdos_lcm.h), where the `gdos` viewer shows every host's log.
//
// Levels (RACK's): print < error < warning < info < detail. A source logs a record
// when its level is at most the source's threshold; `print` always passes.
//
// Format strings are printf's, checked at compile time against the argument types
// (a consteval constructor, like std::format_string): a mismatch does not compile.
// Supported: flags `-+ #0'`, width and precision (digits or `*`), length modifiers
// hh h l ll L j z t q, conversions d i u o x X c s p f F e E g G a A and `%%`. Not
// supported (compile error): %n, %m, positional arguments (%1$d), wide %lc/%ls.
// Arguments: integers (any width; bool and unscoped enums promote), float, double,
// long double, const char* / char arrays / std::string_view / std::string (copied,
// at most kMaxStringBytes and what fits the record), object pointers for %p (a char
// pointer must be cast to const void* for %p), and a TiMS address (tims::Address)
// for %s: it prints as its name, `Ladar(0/1)`, with the width and precision given.
// The format string must be a string literal: the record keeps only its pointer.
//
// Real-time contract:
//   log(), Component::log_*(): RT-safe from a task the executor started (it bound a
//     ring to the thread). From any other thread (main, init(), cleanup(), tool
//     threads) the call is NOT RT-safe: it formats at once and queues the text under
//     a lock (such threads are never RT in RACK-RT: components do not make threads).
//   LogRing: try_claim/commit/take_pending_drops by the producer only (one thread),
//     peek/pop by the consumer only; counters from any thread. write_record() RT-safe.
//   Hub: everything is non-RT (construction, make_ring, drain, publish_text).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "rack/rt/clock.h"
#include "rack/tims/address.h"

namespace rack::gdos {

// RACK's levels. Numerically ordered: a record passes when level <= threshold.
enum class Level : uint8_t { kPrint = 0, kError = 1, kWarning = 2, kInfo = 3, kDetail = 4 };
inline constexpr Level kDefaultLevel = Level::kInfo;
[[nodiscard]] const char* describe(Level level) noexcept;  // "warning"
[[nodiscard]] char letter(Level level) noexcept;           // 'W'
// "print", "error", "warning", "info", "detail"; nullopt otherwise. RT-safe.
[[nodiscard]] std::optional<Level> parse_level(std::string_view text) noexcept;
inline constexpr const char* kLevelNames = "print, error, warning, info, detail";

// ---- compile-time format check -----------------------------------------------

enum class ArgKind : uint8_t { kInt = 1, kDouble, kLongDouble, kPointer, kString, kAddress, kUnsupported };

struct ArgInfo {
  ArgKind kind = ArgKind::kUnsupported;
  uint8_t size = 0;  // after default promotion (ints: 4 or 8)
  bool is_signed = false;
};

template <class E, bool = std::is_enum_v<E>>
struct IsUnscopedEnum : std::false_type {};
template <class E>
struct IsUnscopedEnum<E, true> : std::bool_constant<std::is_convertible_v<E, std::underlying_type_t<E>>> {};

template <class T>
consteval ArgInfo arg_info() {
  using U = std::remove_cvref_t<T>;
  using D = std::decay_t<U>;
  if constexpr (std::is_same_v<D, bool>) {
    return {ArgKind::kInt, 4, true};
  } else if constexpr (std::is_integral_v<D>) {
    return {ArgKind::kInt, static_cast<uint8_t>(sizeof(D) < sizeof(int) ? sizeof(int) : sizeof(D)),
            std::is_signed_v<D> || sizeof(D) < sizeof(int)};
  } else if constexpr (IsUnscopedEnum<D>::value) {
    return arg_info<std::underlying_type_t<D>>();  // unscoped enum: promotes like its type
  } else if constexpr (std::is_same_v<D, float> || std::is_same_v<D, double>) {
    return {ArgKind::kDouble, 8, true};
  } else if constexpr (std::is_same_v<D, long double>) {
    return {ArgKind::kLongDouble, static_cast<uint8_t>(sizeof(long double)), true};
  } else if constexpr (std::is_same_v<D, const char*> || std::is_same_v<D, char*>) {
    return {ArgKind::kString, 8, false};  // a string, never a pointer for %p
  } else if constexpr (std::is_convertible_v<const U&, std::string_view> && !std::is_pointer_v<D>) {
    return {ArgKind::kString, 8, false};
  } else if constexpr (std::is_same_v<D, tims::Address>) {
    return {ArgKind::kAddress, 4, false};
  } else if constexpr (std::is_pointer_v<D> || std::is_null_pointer_v<D>) {
    return {ArgKind::kPointer, 8, false};
  } else {
    return {};
  }
}

enum class FormatError : uint8_t {
  kOk,
  kTooFewArguments,
  kTooManyArguments,
  kArgumentTypeMismatch,  // e.g. an int for %f, a double for %d, a long for %d
  kUnsupportedArgument,   // a type GDOS cannot copy (a class, a scoped enum, ...)
  kUnknownConversion,     // not a printf conversion, or %n / %m / %lc / %ls
  kPositionalArgument,    // %1$d
  kIncompleteConversion,  // a '%' at the end
  kTooManyArguments16,    // more than kMaxArgs arguments
};

inline constexpr std::size_t kMaxArgs = 16;

// One parsed conversion: where it is and what it consumes. constexpr: used at
// compile time by the check and at run time by the formatter.
struct Conversion {
  std::size_t begin = 0;  // index of '%'
  std::size_t end = 0;    // one past the conversion character
  bool star_width = false;
  bool star_precision = false;
  char length[3] = {};  // "", "h", "hh", "l", "ll", "L", "j", "z", "t", "q"
  char conversion = 0;  // 'd', ..., or '%'
};

// Parses the conversion starting at fmt[pos] == '%'. false: malformed (err set).
constexpr bool parse_conversion(std::string_view fmt, std::size_t pos, Conversion& c, FormatError& err) {
  c = Conversion{};
  c.begin = pos;
  std::size_t i = pos + 1;
  if (i >= fmt.size()) {
    err = FormatError::kIncompleteConversion;
    return false;
  }
  if (fmt[i] == '%') {
    c.conversion = '%';
    c.end = i + 1;
    return true;
  }
  // Positional arguments: digits followed by '$'.
  {
    std::size_t j = i;
    while (j < fmt.size() && fmt[j] >= '0' && fmt[j] <= '9') ++j;
    if (j > i && j < fmt.size() && fmt[j] == '$') {
      err = FormatError::kPositionalArgument;
      return false;
    }
  }
  while (i < fmt.size() &&
         (fmt[i] == '-' || fmt[i] == '+' || fmt[i] == ' ' || fmt[i] == '#' || fmt[i] == '0' || fmt[i] == '\'')) {
    ++i;
  }
  if (i < fmt.size() && fmt[i] == '*') {
    c.star_width = true;
    ++i;
  } else
    while (i < fmt.size() && fmt[i] >= '0' && fmt[i] <= '9') ++i;
  if (i < fmt.size() && fmt[i] == '.') {
    ++i;
    if (i < fmt.size() && fmt[i] == '*') {
      c.star_precision = true;
      ++i;
    } else
      while (i < fmt.size() && fmt[i] >= '0' && fmt[i] <= '9') ++i;
  }
  if (i < fmt.size()) {
    const char l = fmt[i];
    if ((l == 'h' || l == 'l') && i + 1 < fmt.size() && fmt[i + 1] == l) {
      c.length[0] = l;
      c.length[1] = l;
      i += 2;
    } else if (l == 'h' || l == 'l' || l == 'L' || l == 'j' || l == 'z' || l == 't' || l == 'q') {
      c.length[0] = l;
      ++i;
    }
  }
  if (i >= fmt.size()) {
    err = FormatError::kIncompleteConversion;
    return false;
  }
  const char conv = fmt[i];
  switch (conv) {
    case 'd':
    case 'i':
    case 'u':
    case 'o':
    case 'x':
    case 'X':
    case 'c':
    case 's':
    case 'p':
    case 'f':
    case 'F':
    case 'e':
    case 'E':
    case 'g':
    case 'G':
    case 'a':
    case 'A': break;
    default: err = FormatError::kUnknownConversion; return false;
  }
  if ((conv == 'c' || conv == 's' || conv == 'p') && c.length[0] != 0) {
    err = FormatError::kUnknownConversion;  // %lc, %ls (wide) or a length on %p
    return false;
  }
  c.conversion = conv;
  c.end = i + 1;
  return true;
}

// 8 for the 64-bit length modifiers, 4 otherwise (hh and h promote to int).
constexpr uint8_t integer_size(const char* length) {
  if (length[0] == 0 || length[0] == 'h') return 4;
  return 8;  // l ll j z t q on x86-64 / LP64
}

constexpr bool is_integer_conversion(char c) {
  return c == 'd' || c == 'i' || c == 'u' || c == 'o' || c == 'x' || c == 'X' || c == 'c';
}
constexpr bool is_float_conversion(char c) {
  return c == 'f' || c == 'F' || c == 'e' || c == 'E' || c == 'g' || c == 'G' || c == 'a' || c == 'A';
}

// Checks a format string against argument infos. Usable at compile time and at run
// time (the formatter re-checks every record it reads: defence against corruption).
constexpr FormatError check_format(std::string_view fmt, const ArgInfo* args, std::size_t count) {
  if (count > kMaxArgs) return FormatError::kTooManyArguments16;
  std::size_t next = 0;
  auto take_int = [&](FormatError& e) {
    if (next >= count) {
      e = FormatError::kTooFewArguments;
      return false;
    }
    const ArgInfo a = args[next++];
    if (a.kind == ArgKind::kUnsupported) {
      e = FormatError::kUnsupportedArgument;
      return false;
    }
    if (a.kind != ArgKind::kInt || a.size != 4) {
      e = FormatError::kArgumentTypeMismatch;
      return false;
    }
    return true;
  };
  for (std::size_t i = 0; i < fmt.size(); ++i) {
    if (fmt[i] != '%') continue;
    Conversion c;
    FormatError e = FormatError::kOk;
    if (!parse_conversion(fmt, i, c, e)) return e;
    i = c.end - 1;
    if (c.conversion == '%') continue;
    if (c.star_width && !take_int(e)) return e;
    if (c.star_precision && !take_int(e)) return e;
    if (next >= count) return FormatError::kTooFewArguments;
    const ArgInfo a = args[next++];
    if (a.kind == ArgKind::kUnsupported) return FormatError::kUnsupportedArgument;
    if (is_integer_conversion(c.conversion)) {
      if (a.kind != ArgKind::kInt) return FormatError::kArgumentTypeMismatch;
      if (a.size != integer_size(c.length)) return FormatError::kArgumentTypeMismatch;
    } else if (is_float_conversion(c.conversion)) {
      const bool want_long = c.length[0] == 'L';
      if (c.length[0] != 0 && c.length[0] != 'L' && !(c.length[0] == 'l' && c.length[1] == 0)) {
        return FormatError::kUnknownConversion;  // %hf, %llf, %zf ...
      }
      if (a.kind != (want_long ? ArgKind::kLongDouble : ArgKind::kDouble)) return FormatError::kArgumentTypeMismatch;
    } else if (c.conversion == 's') {
      if (a.kind != ArgKind::kString && a.kind != ArgKind::kAddress) return FormatError::kArgumentTypeMismatch;
    } else if (c.conversion == 'p') {
      if (a.kind != ArgKind::kPointer) return FormatError::kArgumentTypeMismatch;
    }
  }
  return next == count ? FormatError::kOk : FormatError::kTooManyArguments;
}

template <class... Args>
constexpr FormatError check_format_for(std::string_view fmt) {
  if constexpr (sizeof...(Args) == 0) {
    return check_format(fmt, nullptr, 0);
  } else {
    constexpr ArgInfo kInfos[] = {arg_info<Args>()...};
    return check_format(fmt, kInfos, sizeof...(Args));
  }
}

// Not constexpr on purpose: calling one in a consteval context is the compile error,
// and its name is what the compiler prints.
void gdos_format_error_too_few_arguments_for_the_format();
void gdos_format_error_too_many_arguments_for_the_format();
void gdos_format_error_argument_type_does_not_match_its_conversion();
void gdos_format_error_argument_type_cannot_be_logged();
void gdos_format_error_unsupported_conversion();
void gdos_format_error_positional_arguments_unsupported();
void gdos_format_error_percent_at_end_of_format();
void gdos_format_error_more_than_16_arguments();

// A format string checked at compile time against Args (a string literal only).
template <class... Args>
class FormatString {
 public:
  template <std::size_t N>
  consteval FormatString(const char (&text)[N]) : text_(text) {  // NOLINT: implicit on purpose
    switch (check_format_for<Args...>(std::string_view(text, N - 1))) {
      case FormatError::kOk: break;
      case FormatError::kTooFewArguments: gdos_format_error_too_few_arguments_for_the_format(); break;
      case FormatError::kTooManyArguments: gdos_format_error_too_many_arguments_for_the_format(); break;
      case FormatError::kArgumentTypeMismatch: gdos_format_error_argument_type_does_not_match_its_conversion(); break;
      case FormatError::kUnsupportedArgument: gdos_format_error_argument_type_cannot_be_logged(); break;
      case FormatError::kUnknownConversion: gdos_format_error_unsupported_conversion(); break;
      case FormatError::kPositionalArgument: gdos_format_error_positional_arguments_unsupported(); break;
      case FormatError::kIncompleteConversion: gdos_format_error_percent_at_end_of_format(); break;
      case FormatError::kTooManyArguments16: gdos_format_error_more_than_16_arguments(); break;
    }
  }
  [[nodiscard]] constexpr const char* c_str() const noexcept { return text_; }

 private:
  const char* text_;
};

template <class... Args>
using Format = FormatString<std::type_identity_t<Args>...>;

// ---- records and the per-task ring ---------------------------------------------

inline constexpr std::size_t kSlotBytes = 256;
inline constexpr std::size_t kMaxStringBytes = 160;  // per string argument (and what fits)

class LogSource;

// One record in a ring slot: the header, then per argument a kind byte and its
// value (integers and pointers 8 bytes, doubles 8, long doubles 16, addresses 4,
// strings a 2-byte length and the bytes). Native byte order: it never leaves the
// process.
struct RecordHeader {
  const char* format = nullptr;       // a string literal (static storage)
  const LogSource* source = nullptr;  // null: `address` and `text` only
  int64_t mono_ns = 0;                // CLOCK_MONOTONIC at the call
  uint32_t address = 0;               // source address
  uint32_t dropped_before = 0;        // records this ring dropped just before this one
  uint16_t bytes = 0;                 // payload bytes after the header
  uint8_t level = 0;
  uint8_t nargs = 0;
  uint8_t truncated = 0;  // a string argument was cut
  uint8_t reserved[3] = {};
};
inline constexpr std::size_t kPayloadBytes = kSlotBytes - sizeof(RecordHeader);

// Fixed-slot single-producer single-consumer ring (a task's log queue).
// Producer: the task bound to it. Consumer: the host's GDOS thread.
class LogRing {
 public:
  // `slots` is rounded up to a power of two (at least 2). Not RT-safe.
  explicit LogRing(uint32_t slots, std::string owner = {});
  LogRing(const LogRing&) = delete;
  LogRing& operator=(const LogRing&) = delete;

  // Producer (RT-safe): a free slot, or nullptr when full (the drop is counted).
  [[nodiscard]] std::byte* try_claim() noexcept {
    const uint64_t head = head_.load(std::memory_order_relaxed);
    // SYNC POINT: acquire pairs with the consumer's release in pop(): the slot is
    // free only once the consumer finished reading it.
    if (head - tail_.load(std::memory_order_acquire) >= capacity_) {
      dropped_.store(dropped_.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      ++pending_drops_;
      return nullptr;
    }
    return slot(head);
  }
  // Producer (RT-safe): publishes the slot claimed last.
  void commit() noexcept {
    // SYNC POINT: release makes the slot's bytes visible before the new head.
    head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }
  // Producer: drops since the last committed record (moved into that record).
  [[nodiscard]] uint32_t take_pending_drops() noexcept {
    const uint32_t n = pending_drops_;
    pending_drops_ = 0;
    return n;
  }

  // Consumer: the oldest record, or nullptr when empty.
  [[nodiscard]] const std::byte* peek() const noexcept {
    const uint64_t tail = tail_.load(std::memory_order_relaxed);
    // SYNC POINT: acquire pairs with commit()'s release.
    if (tail == head_.load(std::memory_order_acquire)) return nullptr;
    return slot(tail);
  }
  void pop() noexcept { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

  [[nodiscard]] uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint64_t written() const noexcept { return head_.load(std::memory_order_relaxed); }
  [[nodiscard]] uint32_t capacity() const noexcept { return static_cast<uint32_t>(capacity_); }
  [[nodiscard]] const std::string& owner() const noexcept { return owner_; }

 private:
  [[nodiscard]] std::byte* slot(uint64_t index) const noexcept {
    return storage_.get() + (index & (capacity_ - 1)) * kSlotBytes;
  }
  uint64_t capacity_;
  std::unique_ptr<std::byte[]> storage_;
  std::string owner_;
  alignas(64) std::atomic<uint64_t> head_{0};  // written by the producer
  uint32_t pending_drops_ = 0;                 // producer only
  std::atomic<uint64_t> dropped_{0};           // producer writes (relaxed: a statistic)
  alignas(64) std::atomic<uint64_t> tail_{0};  // written by the consumer
};

// Who logs: a component (its address, name and level), or the executor.
class LogSource {
 public:
  LogSource() = default;
  LogSource(tims::Address address, std::string name, Level level = kDefaultLevel)
      : address_(address), name_(std::move(name)), level_(level) {}
  LogSource(const LogSource&) = delete;
  LogSource& operator=(const LogSource&) = delete;

  void set_identity(tims::Address address, std::string name) {  // not RT-safe (set-up)
    address_ = address;
    name_ = std::move(name);
  }
  [[nodiscard]] tims::Address address() const noexcept { return address_; }
  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  // Relaxed: a threshold; a log call may see the old one for a moment.
  [[nodiscard]] Level level() const noexcept { return level_.load(std::memory_order_relaxed); }
  void set_level(Level l) noexcept { level_.store(l, std::memory_order_relaxed); }
  [[nodiscard]] bool enabled(Level l) const noexcept { return l == Level::kPrint || l <= level(); }

 private:
  tims::Address address_;
  std::string name_;
  std::atomic<Level> level_{kDefaultLevel};
};

// ---- the log call ----------------------------------------------------------------

namespace detail {

class Writer {
 public:
  Writer(std::byte* out, std::size_t capacity) noexcept : out_(out), capacity_(capacity) {}
  [[nodiscard]] std::size_t size() const noexcept { return used_; }
  [[nodiscard]] bool truncated() const noexcept { return truncated_; }

  template <class T>
  void put(const T& value) noexcept {
    using U = std::remove_cvref_t<T>;
    using D = std::decay_t<U>;
    constexpr ArgInfo kInfo = arg_info<T>();
    if constexpr (kInfo.kind == ArgKind::kInt) {
      if constexpr (std::is_enum_v<D>) {
        put(static_cast<std::underlying_type_t<D>>(value));
      } else if constexpr (std::is_signed_v<D>) {
        put_raw(ArgKind::kInt, static_cast<int64_t>(value));
      } else {
        put_raw(ArgKind::kInt, static_cast<uint64_t>(value));
      }
    } else if constexpr (kInfo.kind == ArgKind::kDouble) {
      put_raw(ArgKind::kDouble, static_cast<double>(value));
    } else if constexpr (kInfo.kind == ArgKind::kLongDouble) {
      put_raw(ArgKind::kLongDouble, value);
    } else if constexpr (kInfo.kind == ArgKind::kAddress) {
      put_raw(ArgKind::kAddress, value.raw());
    } else if constexpr (kInfo.kind == ArgKind::kPointer) {
      put_raw(ArgKind::kPointer, reinterpret_cast<uint64_t>(static_cast<const volatile void*>(value)));
    } else if constexpr (kInfo.kind == ArgKind::kString) {
      if constexpr (std::is_array_v<U>) {
        constexpr std::size_t kN = std::extent_v<U> < kMaxStringBytes ? std::extent_v<U> : kMaxStringBytes;
        std::size_t n = strnlen(value, kN);
        if (n > kN) n = kN;  // strnlen's bound, spelled out for the compiler's bounds check
        put_string(value, n);
      } else if constexpr (std::is_pointer_v<D>) {
        // What glibc prints for a null %s (an array as long as any string, so the
        // compiler can see the copy below stays in bounds).
        static constexpr char kNull[kMaxStringBytes + 1] = "(null)";
        if (value == nullptr) put_string(kNull, 6);
        else put_string(value, strnlen(value, kMaxStringBytes + 1));
      } else {
        const std::string_view s(value);
        put_string(s.data(), s.size());
      }
    }
  }

 private:
  template <class V>
  void put_raw(ArgKind kind, const V& v) noexcept {
    // Sizes were reserved by the caller (fixed part of the record); always fits.
    out_[used_] = static_cast<std::byte>(kind);
    std::memcpy(out_ + used_ + 1, &v, sizeof v);
    used_ += 1 + sizeof v;
  }
// GCC 12 inlines put_string into log calls whose string argument is one of several
// literals and then warns that the copy may read past the shortest of them
// (-Warray-bounds, -Wstringop-overread): false, n is that string's own length.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Warray-bounds"
#pragma GCC diagnostic ignored "-Wstringop-overread"
#endif
  void put_string(const char* s, std::size_t n) noexcept {
    // Kind, 2-byte length, bytes; what does not fit is cut (and flagged).
    std::size_t room = capacity_ - used_ - 3 - reserve_after_;  // never negative: fixed parts were reserved
    if (n > kMaxStringBytes) {
      n = kMaxStringBytes;
      truncated_ = true;
    }
    if (n > room) {
      n = room;
      truncated_ = true;
    }
    const auto len = static_cast<uint16_t>(n);
    out_[used_] = static_cast<std::byte>(ArgKind::kString);
    std::memcpy(out_ + used_ + 1, &len, 2);
    std::memcpy(out_ + used_ + 3, s, n);
    used_ += 3 + n;
  }
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

 public:
  // Fixed bytes still needed by the arguments after the next one (strings must
  // leave them room).
  void set_reserve_after(std::size_t bytes) noexcept { reserve_after_ = bytes; }

 private:
  std::size_t reserve_after_ = 0;
  std::byte* out_;
  std::size_t capacity_;
  std::size_t used_ = 0;
  bool truncated_ = false;
};

// Fixed bytes an argument needs (strings: kind + length only).
template <class T>
consteval std::size_t fixed_bytes() {
  constexpr ArgInfo kInfo = arg_info<T>();
  if constexpr (kInfo.kind == ArgKind::kString) return 3;
  else if constexpr (kInfo.kind == ArgKind::kLongDouble) return 1 + sizeof(long double);
  else if constexpr (kInfo.kind == ArgKind::kAddress) return 1 + 4;
  else return 1 + 8;
}

template <class... Args>
consteval std::size_t total_fixed_bytes() {
  return (std::size_t{0} + ... + fixed_bytes<Args>());
}

// The calling thread's ring (bound by the executor), or nullptr.
[[nodiscard]] LogRing* thread_ring() noexcept;

}  // namespace detail

// One argument, decoded (from a ring record) or taken as passed (threads without a
// ring). Strings are views: valid as long as the record or the argument is.
struct Value {
  ArgKind kind = ArgKind::kUnsupported;
  uint64_t bits = 0;   // kInt (sign- or zero-extended), kPointer, kAddress
  double d = 0;        // kDouble
  long double ld = 0;  // kLongDouble
  std::string_view s;  // kString
};

template <class T>
Value to_value(const T& value) noexcept {
  using U = std::remove_cvref_t<T>;
  using D = std::decay_t<U>;
  constexpr ArgInfo kInfo = arg_info<T>();
  Value v;
  v.kind = kInfo.kind;
  if constexpr (kInfo.kind == ArgKind::kInt) {
    if constexpr (std::is_enum_v<D>) return to_value(static_cast<std::underlying_type_t<D>>(value));
    else if constexpr (std::is_signed_v<D>) v.bits = static_cast<uint64_t>(static_cast<int64_t>(value));
    else v.bits = static_cast<uint64_t>(value);
  } else if constexpr (kInfo.kind == ArgKind::kDouble) {
    v.d = static_cast<double>(value);
  } else if constexpr (kInfo.kind == ArgKind::kLongDouble) {
    v.ld = value;
  } else if constexpr (kInfo.kind == ArgKind::kAddress) {
    v.bits = value.raw();
  } else if constexpr (kInfo.kind == ArgKind::kPointer) {
    v.bits = reinterpret_cast<uint64_t>(static_cast<const volatile void*>(value));
  } else if constexpr (kInfo.kind == ArgKind::kString) {
    if constexpr (std::is_array_v<U>) v.s = std::string_view(value, strnlen(value, std::extent_v<U>));
    else if constexpr (std::is_pointer_v<D>)
      v.s = value == nullptr ? std::string_view("(null)") : std::string_view(value);
    else v.s = std::string_view(value);
  }
  return v;
}

namespace detail {
// Slow path for threads without a ring: formats now, queues the text. Not RT-safe.
void log_unbound(const LogSource& source, Level level, const char* format, const Value* values,
                 std::size_t count) noexcept;
}  // namespace detail

// Encodes one record into `ring`. RT-safe. false: the ring was full (counted).
template <class... Args>
bool write_record(LogRing& ring, const LogSource* source, tims::Address address, Level level, const char* format,
                  const Args&... args) noexcept {
  static_assert(detail::total_fixed_bytes<Args...>() <= kPayloadBytes, "too many arguments for one GDOS record");
  std::byte* slot = ring.try_claim();
  if (slot == nullptr) return false;
  RecordHeader h;
  h.format = format;
  h.source = source;
  h.mono_ns = rt::monotonic_ns();
  h.address = address.raw();
  h.level = static_cast<uint8_t>(level);
  h.nargs = static_cast<uint8_t>(sizeof...(Args));
  detail::Writer w(slot + sizeof(RecordHeader), kPayloadBytes);
  [[maybe_unused]] std::size_t remaining_fixed = detail::total_fixed_bytes<Args...>();
  // Each argument in order; strings may use what the fixed parts leave over.
  (([&] {
     remaining_fixed -= detail::fixed_bytes<Args>();
     w.set_reserve_after(remaining_fixed);
     w.put(args);
   }()),
   ...);
  h.bytes = static_cast<uint16_t>(w.size());
  h.truncated = w.truncated() ? 1 : 0;
  h.dropped_before = ring.take_pending_drops();
  std::memcpy(slot, &h, sizeof h);
  ring.commit();
  return true;
}

// Logs one record for `source` at `level`. RT-safe from an executor task (see top).
template <class... Args>
void log(const LogSource& source, Level level, Format<Args...> format, const Args&... args) noexcept {
  if (!source.enabled(level)) return;
  if (LogRing* ring = detail::thread_ring()) {
    (void)write_record(ring[0], &source, source.address(), level, format.c_str(), args...);
    return;
  }
  if constexpr (sizeof...(Args) == 0) {
    detail::log_unbound(source, level, format.c_str(), nullptr, 0);
  } else {
    const Value values[] = {to_value(args)...};
    detail::log_unbound(source, level, format.c_str(), values, sizeof...(Args));
  }
}

// Binds a ring to the calling thread (the executor does this at task start; tests
// and benchmarks may too). nullptr unbinds. Not RT-safe (first TLS touch).
void bind_thread_ring(LogRing* ring) noexcept;

// ---- formatting (non-RT) -----------------------------------------------------

// Formats a record's payload with its format. Returns false on a record whose
// arguments do not match its format (corruption; the text says so). Not RT-safe.
bool format_record(const RecordHeader& header, const std::byte* payload, std::string& out);

// printf of one format with decoded values, one conversion at a time through
// snprintf (so every conversion prints exactly as printf would). Appends to `out`.
// false (and a note in `out`) when the values do not match the format. Not RT-safe.
bool format_values(std::string_view format, const Value* values, std::size_t count, std::string& out);
// Decodes a ring record's payload into values (views into `payload`). false when
// the payload is inconsistent. Not RT-safe (but allocation-free).
bool decode_payload(const RecordHeader& header, const std::byte* payload, Value (&values)[kMaxArgs]);

// A formatted record, as sinks receive it.
struct Record {
  Level level = Level::kInfo;
  int64_t time_ns = 0;  // host clock (CLOCK_REALTIME)
  int64_t mono_ns = 0;
  uint64_t sequence = 0;  // per host, counts every record handed to the sinks
  tims::Address source;
  std::string_view name;  // source name ("" when unknown)
  uint32_t dropped_before = 0;
  std::string_view text;
};

// "2026-11-21T23:41:02.123456Z W generator Generator(0/1): text\n" (rackd's
// stderr). append_line reuses the capacity of `out`. Not RT-safe.
[[nodiscard]] std::string format_line(const Record& r);
void append_line(const Record& r, std::string& out);

// ---- the host's hub ----------------------------------------------------------

struct HubCounters {
  uint64_t records = 0;    // handed to the sinks
  uint64_t dropped = 0;    // lost in full rings (all rings) and a full text queue
  uint64_t malformed = 0;  // records whose arguments did not match their format
  uint64_t unbound = 0;    // records from threads without a ring (formatted at once)
};

// All rings of one host, plus the queue of preformatted text; drained in time order
// by one non-RT thread. Not RT-safe (except what LogRing's producer side offers).
class Hub {
 public:
  Hub();
  ~Hub();
  Hub(const Hub&) = delete;
  Hub& operator=(const Hub&) = delete;

  // A new ring for one task; the Hub owns it. Not RT-safe; thread-safe.
  LogRing& make_ring(uint32_t slots, std::string owner);

  // Queues preformatted text (non-RT entry point: executor events, mode-switch
  // reports, threads without a ring). Thread-safe; allocates. At most 65536 texts
  // wait; beyond that they are dropped and counted.
  void publish_text(Level level, tims::Address source, std::string name, std::string text);

  // Formats every queued record, oldest first across all rings (records of one
  // source keep their order), and hands each to `sink`. One thread at a time.
  // Returns the number of records. Rings' drops are reported as a warning record
  // of the ring's source ("N log records dropped: ring full").
  std::size_t drain(const std::function<void(const Record&)>& sink);

  [[nodiscard]] HubCounters counters() const noexcept;

  // The hub that threads without a ring queue their text to (the executor installs
  // its own at start). nullptr: such records go straight to stderr.
  static void set_process_hub(Hub* hub) noexcept;
  static Hub* process_hub() noexcept;

 private:
  struct Text {
    int64_t mono_ns;
    Level level;
    tims::Address source;
    std::string name;
    std::string text;
  };
  std::mutex rings_mutex_;  // make_ring vs drain (non-RT only)
  std::vector<std::unique_ptr<LogRing>> rings_;
  std::vector<uint64_t> budget_;  // per ring, for one drain pass
  std::mutex text_mutex_;
  std::deque<Text> texts_;
  std::deque<Text> draining_;  // drain() only
  std::string scratch_;
  uint64_t sequence_ = 0;
  static constexpr std::size_t kMaxQueuedTexts = 65536;
  // Relaxed: statistics, read by status reports; nothing is published through them.
  std::atomic<uint64_t> records_{0}, malformed_{0}, unbound_{0}, texts_dropped_{0};
  friend void detail::log_unbound(const LogSource&, Level, const char*, const Value*, std::size_t) noexcept;
};

}  // namespace rack::gdos
