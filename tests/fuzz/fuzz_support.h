// What the fuzz harnesses share: a reader that takes typed values off the front of
// the fuzzer's input (LLVM's FuzzedDataProvider does this, but GCC builds lack it),
// and FUZZ_CHECK, which aborts with file:line when a property of a decoder does not
// hold, in the libFuzzer build (a crash libFuzzer saves) and in the replay build alike.
//
// Each harness defines `extern "C" int LLVMFuzzerTestOneInput(const uint8_t*, size_t)`
// and returns 0; see tests/fuzz/README.md.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <span>

namespace rack::fuzz {

[[noreturn]] inline void check_failed(const char* what, const char* file, int line) {
  std::fprintf(stderr, "%s:%d: fuzz check failed: %s\n", file, line, what);
  std::abort();
}

// Takes bytes off the front of the input; past the end it gives zeros (a short input
// is still a valid one, so the fuzzer need not learn lengths first).
class FuzzInput {
 public:
  FuzzInput(const uint8_t* data, std::size_t size) : data_(data), size_(size) {}

  [[nodiscard]] bool empty() const noexcept { return pos_ >= size_; }
  [[nodiscard]] std::size_t remaining() const noexcept { return size_ - pos_; }

  template <typename T>
  [[nodiscard]] T take() noexcept {
    T v{};
    const std::size_t n = std::min(sizeof v, remaining());
    if (n > 0) std::memcpy(&v, data_ + pos_, n);
    pos_ += n;
    return v;
  }
  [[nodiscard]] uint8_t byte() noexcept { return take<uint8_t>(); }

  // Up to n bytes (fewer at the end).
  [[nodiscard]] std::span<const uint8_t> bytes(std::size_t n) noexcept {
    const std::size_t k = std::min(n, remaining());
    std::span<const uint8_t> s(data_ + pos_, k);
    pos_ += k;
    return s;
  }
  [[nodiscard]] std::span<const uint8_t> rest() noexcept { return bytes(remaining()); }

 private:
  const uint8_t* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

}  // namespace rack::fuzz

// A property of the code under test; aborts with its text and place when false.
#define FUZZ_CHECK(cond) ((cond) ? static_cast<void>(0) : ::rack::fuzz::check_failed(#cond, __FILE__, __LINE__))
