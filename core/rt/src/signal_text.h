// A text in a caller's buffer, built without allocation, lock or system call:
// async-signal-safe (the crash handler formats its report with it). Characters past
// the buffer's capacity (less one) are dropped. Internal to core/rt: the mode-switch
// detector and its report format (rack/rt/modeswitch_report.h).
//
// Real-time contract: RT-safe and async-signal-safe. Thread-safety: one thread per Text.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace rack::rt::modeswitch {

class Text {
 public:
  Text(char* buf, std::size_t cap) : buf_(buf), cap_(cap) {}
  Text& s(const char* t) noexcept {
    while (t != nullptr && *t != '\0') c(*t++);
    return *this;
  }
  Text& s(std::string_view t) noexcept {
    for (char ch : t) c(ch);
    return *this;
  }
  Text& c(char ch) noexcept {
    if (len_ + 1 < cap_) buf_[len_++] = ch;
    return *this;
  }
  Text& u(uint64_t v) noexcept {
    char tmp[24];
    int n = 0;
    do {
      tmp[n++] = static_cast<char>('0' + v % 10);
      v /= 10;
    } while (v != 0);
    while (n > 0) c(tmp[--n]);
    return *this;
  }
  Text& i(int64_t v) noexcept {
    if (v < 0) {
      c('-');
      return u(static_cast<uint64_t>(-(v + 1)) + 1);
    }
    return u(static_cast<uint64_t>(v));
  }
  Text& hex(uint64_t v, int min_digits = 1) noexcept {
    static constexpr char kDigits[] = "0123456789abcdef";
    char tmp[16];
    int n = 0;
    do {
      tmp[n++] = kDigits[v & 15u];
      v >>= 4;
    } while (v != 0 || n < min_digits);
    s("0x");
    while (n > 0) c(tmp[--n]);
    return *this;
  }
  [[nodiscard]] std::size_t size() const noexcept { return len_; }
  [[nodiscard]] const char* data() const noexcept { return buf_; }
  [[nodiscard]] std::string_view view() const noexcept { return {buf_, len_}; }
  void clear() noexcept { len_ = 0; }
  // Lets `write(char* at, std::size_t room)` add to the text: it returns the bytes it
  // wrote, at most room - 1 (report::format's contract).
  template <typename Write>
  Text& append(Write write) noexcept {
    if (len_ < cap_) len_ += write(buf_ + len_, cap_ - len_);
    return *this;
  }

 private:
  char* buf_;
  std::size_t cap_;
  std::size_t len_ = 0;
};

}  // namespace rack::rt::modeswitch
