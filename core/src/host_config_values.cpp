// Host files: one key's value, checked (type, range, name rules, LCM URL) and converted;
// every error with the file, line and column of the node.
#include "host_loader.h"

#include <cmath>

#include "rack/tims/lcm_url.h"

namespace rack {

void HostValueReader::error(const YAML::Mark& mark, const std::string& message) {
  report_.errors.push_back({report_.file, mark.line + 1, mark.column + 1, message});
}

void HostValueReader::warn(const YAML::Mark& mark, const std::string& message) {
  report_.warnings.push_back({report_.file, mark.line + 1, mark.column + 1, message});
}

// Checks that a map has only known keys; reports each unknown one.
void HostValueReader::check_keys(const YAML::Node& map, const std::set<std::string>& known, const std::string& where) {
  for (auto it = map.begin(); it != map.end(); ++it) {
    const std::string key = it->first.Scalar();
    if (known.count(key) == 0) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      error(it->first.Mark(), "unknown key '" + key + "' in " + where + " (known: " + list + ")");
    }
  }
}

bool HostValueReader::get_int_range(const YAML::Node& map, const char* key, int64_t lo, int64_t hi, int64_t& out,
                                    const std::string& what) {
  int64_t v = 0;
  if (!get(map, key, v, what)) return false;
  if (v < lo || v > hi) {
    error(map[key].Mark(), std::string("'") + key + "' = " + std::to_string(v) + " is outside " + std::to_string(lo) +
                               ".." + std::to_string(hi));
    return false;
  }
  out = v;
  return true;
}

bool HostValueReader::get_positive_ms(const YAML::Node& map, const char* key, int64_t& out_ns) {
  double ms = 0;
  if (!get(map, key, ms, "a number of milliseconds")) return false;
  if (!(ms > 0) || !std::isfinite(ms)) {
    error(map[key].Mark(), std::string("'") + key + "' must be positive, got " + map[key].Scalar());
    return false;
  }
  if (ms > kMaxHostMilliseconds) {
    error(map[key].Mark(), std::string("'") + key + "' = " + map[key].Scalar() + " is above " +
                               std::to_string(static_cast<int64_t>(kMaxHostMilliseconds)) + " ms (a day)");
    return false;
  }
  out_ns = static_cast<int64_t>(std::llround(ms * 1e6));
  if (out_ns <= 0) {
    error(map[key].Mark(), std::string("'") + key + "' is below one nanosecond");
    return false;
  }
  return true;
}

bool HostValueReader::get_ms_range(const YAML::Node& map, const char* key, double lo_ms, double hi_ms, int64_t& out_ns,
                                   const std::string& what) {
  double ms = 0;
  if (!get(map, key, ms, what)) return false;
  if (!std::isfinite(ms) || ms < lo_ms || ms > hi_ms) {
    error(map[key].Mark(), std::string("'") + key + "' = " + map[key].Scalar() + " is outside " +
                               std::to_string(static_cast<int64_t>(lo_ms)) + ".." +
                               std::to_string(static_cast<int64_t>(hi_ms)) + " (" + what + ")");
    return false;
  }
  out_ns = static_cast<int64_t>(std::llround(ms * 1e6));
  return true;
}

// A name: 1..max ASCII letters, digits, '_', '-' (and '.' where `dots`).
bool HostValueReader::valid_name(const std::string& n, std::size_t max, bool dots) {
  if (n.empty() || n.size() > max) return false;
  for (char c : n) {
    const bool letter = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9');
    if (!letter && c != '_' && c != '-' && !(dots && c == '.')) return false;
  }
  return true;
}

// A name as it may be shown in a message: cut to 40 characters, non-ASCII and
// control bytes as '?' (the message itself must stay clean text).
std::string HostValueReader::printable(const std::string& n) {
  std::string out;
  for (char c : n.substr(0, 40)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (n.size() > 40) out += "...(" + std::to_string(n.size()) + " bytes)";
  return out;
}

void HostValueReader::check_url(const YAML::Node& map, const char* key, const std::string& url) {
  if (const auto u = tims::parse_lcm_url(url); !u.ok())
    error(map[key].Mark(), std::string("'") + key + "': " + u.error);
}

}  // namespace rack
