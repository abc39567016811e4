#include "rack/tims/address.h"

#include <array>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <mutex>

namespace rack::tims {

namespace {

struct ClassEntry {
  uint8_t id;
  const char* name;
};

// The framework's own classes. Component classes are not named here: each class
// declaration (components/<class>/CMakeLists.txt) names its TiMS class, and the
// component registry registers that name when it adds the class.
constexpr std::array kBuiltinClasses{
    ClassEntry{classes::kExecutor, "Executor"},
    ClassEntry{classes::kTool, "Tool"},
};

// Registered names: written only before tasks start (register_class_name), read anywhere.
constexpr std::size_t kUserNameLen = 32;
std::array<std::array<char, kUserNameLen>, 256> g_user_names{};
std::mutex g_user_mutex;

}  // namespace

const char* class_name(uint8_t id) noexcept {
  for (const auto& e : kBuiltinClasses) {
    if (e.id == id) return e.name;
  }
  if (g_user_names[id][0] != '\0') return g_user_names[id].data();
  return nullptr;
}

std::optional<uint8_t> class_id(std::string_view name) noexcept {
  for (const auto& e : kBuiltinClasses) {
    if (name == e.name) return e.id;
  }
  for (std::size_t id = 0; id < 256; ++id) {
    if (g_user_names[id][0] != '\0' && name == g_user_names[id].data()) {
      return static_cast<uint8_t>(id);
    }
  }
  return std::nullopt;
}

bool register_class_name(uint8_t id, std::string_view name) {
  std::lock_guard lock(g_user_mutex);
  if (id == 0 || id == classes::kExecutor || id == classes::kTool || id == 0xFF || name.empty() ||
      name.size() >= kUserNameLen) {
    return false;
  }
  if (const auto existing = class_id(name)) return *existing == id;
  if (g_user_names[id][0] != '\0') return false;
  std::memcpy(g_user_names[id].data(), name.data(), name.size());
  g_user_names[id][name.size()] = '\0';
  return true;
}

void Address::format(char* out, std::size_t size) const noexcept {
  if (size == 0) return;
  const char* name = class_name(class_id());
  char num[16];
  if (name == nullptr) {
    std::snprintf(num, sizeof num, "Class0x%02x", class_id());
    name = num;
  }
  if (mailbox() == 0) {
    std::snprintf(out, size, "%s(%u/%u)", name, system(), instance());
  } else {
    std::snprintf(out, size, "%s(%u/%u)#%u", name, system(), instance(), mailbox());
  }
}

std::string Address::str() const {
  char buf[64];
  format(buf, sizeof buf);
  return buf;
}

std::optional<Address> parse_address(std::string_view text) noexcept {
  const auto open = text.find('(');
  const auto close = text.find(')');
  if (open == std::string_view::npos || close == std::string_view::npos || close < open || open == 0) {
    return std::nullopt;
  }
  const std::string_view cls = text.substr(0, open);
  const std::string_view inside = text.substr(open + 1, close - open - 1);
  std::string_view rest = text.substr(close + 1);
  const auto parse_u8 = [](std::string_view s, int base, uint8_t& out) {
    unsigned v = 0;
    const auto* end = s.data() + s.size();
    const auto r = std::from_chars(s.data(), end, v, base);
    if (s.empty() || r.ec != std::errc() || r.ptr != end || v > 255) return false;
    out = static_cast<uint8_t>(v);
    return true;
  };
  uint8_t cid = 0;
  if (const auto known = class_id(cls)) {
    cid = *known;
  } else if (cls.starts_with("Class0x")) {
    if (!parse_u8(cls.substr(7), 16, cid)) return std::nullopt;
  } else if (!parse_u8(cls, 10, cid)) {
    return std::nullopt;
  }
  const auto slash = inside.find('/');
  if (slash == std::string_view::npos) return std::nullopt;
  uint8_t sys = 0, inst = 0, mbx = 0;
  if (!parse_u8(inside.substr(0, slash), 10, sys) || !parse_u8(inside.substr(slash + 1), 10, inst)) {
    return std::nullopt;
  }
  if (!rest.empty()) {
    if (rest[0] != '#' || !parse_u8(rest.substr(1), 10, mbx)) return std::nullopt;
  }
  return Address::make(sys, cid, inst, mbx);
}

}  // namespace rack::tims
