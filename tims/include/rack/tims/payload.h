// How a message body declares its layout, so that a receiver can convert a body of
// the other byte order and tools can print it (rackctl's JSON). A payload type is a
// trivially copyable struct with a field table:
//
//   struct SineData {
//     double value;
//     int64_t counter;
//     static constexpr auto fields() noexcept {
//       return std::array{RACK_FIELD(SineData, value), RACK_FIELD(SineData, counter)};
//     }
//   };
//
// Real-time contract: swap_fields() is RT-safe; everything here is constexpr or RT-safe.
#pragma once

#include <bit>

#include "rack/tims/byte_order.h"
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <type_traits>

namespace rack::tims {

enum class FieldKind : uint8_t { kI8, kU8, kBool, kChar, kI16, kU16, kI32, kU32, kI64, kU64, kF32, kF64 };

struct FieldDesc {
  const char* name;
  FieldKind kind;
  uint32_t offset;  // bytes from the start of the payload
  uint32_t count;   // elements (1 for scalars; N for arrays; char arrays are strings)
};

[[nodiscard]] constexpr uint32_t field_kind_size(FieldKind k) noexcept {
  switch (k) {
    case FieldKind::kI8:
    case FieldKind::kU8:
    case FieldKind::kBool:
    case FieldKind::kChar: return 1;
    case FieldKind::kI16:
    case FieldKind::kU16: return 2;
    case FieldKind::kI32:
    case FieldKind::kU32:
    case FieldKind::kF32: return 4;
    case FieldKind::kI64:
    case FieldKind::kU64:
    case FieldKind::kF64: return 8;
  }
  return 1;
}

template <typename T>
constexpr FieldKind field_kind_of() noexcept {
  using U = std::remove_cv_t<T>;
  if constexpr (std::is_same_v<U, bool>) return FieldKind::kBool;
  else if constexpr (std::is_same_v<U, char>) return FieldKind::kChar;
  else if constexpr (std::is_same_v<U, int8_t>) return FieldKind::kI8;
  else if constexpr (std::is_same_v<U, uint8_t>) return FieldKind::kU8;
  else if constexpr (std::is_same_v<U, int16_t>) return FieldKind::kI16;
  else if constexpr (std::is_same_v<U, uint16_t>) return FieldKind::kU16;
  else if constexpr (std::is_same_v<U, int32_t>) return FieldKind::kI32;
  else if constexpr (std::is_same_v<U, uint32_t>) return FieldKind::kU32;
  else if constexpr (std::is_same_v<U, int64_t>) return FieldKind::kI64;
  else if constexpr (std::is_same_v<U, uint64_t>) return FieldKind::kU64;
  else if constexpr (std::is_same_v<U, float>) return FieldKind::kF32;
  else if constexpr (std::is_same_v<U, double>) return FieldKind::kF64;
  else static_assert(sizeof(T) == 0, "payload fields are fixed-width scalars or arrays of them");
}

template <typename M>
constexpr FieldDesc make_field(const char* name, std::size_t offset) noexcept {
  if constexpr (std::is_array_v<M>) {
    return FieldDesc{name, field_kind_of<std::remove_all_extents_t<M>>(), static_cast<uint32_t>(offset),
                     static_cast<uint32_t>(std::extent_v<M>)};
  } else {
    return FieldDesc{name, field_kind_of<M>(), static_cast<uint32_t>(offset), 1};
  }
}

// Converts every field of a body in place between byte orders. Bytes past `size`
// are left alone; fields that do not fit are skipped. RT-safe.
// GCC 12, inlining this for a small payload, warns that the 8-byte branch could
// touch bytes past it (-Warray-bounds); `at + w > size` rules that out.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Warray-bounds"
#endif
inline void swap_fields(std::span<const FieldDesc> fields, std::byte* body, std::size_t size) noexcept {
  for (const auto& f : fields) {
    const uint32_t w = field_kind_size(f.kind);
    if (w == 1) continue;
    for (uint32_t i = 0; i < f.count; ++i) {
      const std::size_t at = f.offset + std::size_t{i} * w;
      if (at + w > size) return;
      std::byte* p = body + at;
      if (w == 2) {
        uint16_t v;
        std::memcpy(&v, p, 2);
        v = bswap(v);
        std::memcpy(p, &v, 2);
      }
      if (w == 4) {
        uint32_t v;
        std::memcpy(&v, p, 4);
        v = bswap(v);
        std::memcpy(p, &v, 4);
      }
      if (w == 8) {
        uint64_t v;
        std::memcpy(&v, p, 8);
        v = bswap(v);
        std::memcpy(p, &v, 8);
      }
    }
  }
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

// A payload type: trivially copyable, with a static constexpr fields() that returns
// its field table (a member function, so offsetof sees the complete type).
template <typename T>
concept Payload = std::is_trivially_copyable_v<T> && requires {
  {std::span<const FieldDesc>(T::fields())};
};

// The field table of a payload type, with static storage.
template <typename T>
inline constexpr auto fields_of = T::fields();

}  // namespace rack::tims

// One field-table entry; the kind and element count come from the member's type.
#define RACK_FIELD(Type, member) ::rack::tims::make_field<decltype(Type::member)>(#member, offsetof(Type, member))
