// Byte swapping (std::byteswap is C++23). RT-safe, constexpr.
#pragma once

#include <cstdint>

namespace rack::tims {

constexpr uint16_t bswap(uint16_t v) noexcept { return __builtin_bswap16(v); }
constexpr uint32_t bswap(uint32_t v) noexcept { return __builtin_bswap32(v); }
constexpr uint64_t bswap(uint64_t v) noexcept { return __builtin_bswap64(v); }

}  // namespace rack::tims
