// What a tool reads from a host file: its bytes under the host file's rules, and the
// TiMS network to join (URL and key file). The tools (rackctl, gdos, rack-gui) and
// out-of-tree tools use this without the executor or yaml-cpp: the reader parses
// YAML with libyaml's event API and looks only at the keys it needs. rackd reads the
// whole file with rack/core/host_config.h (which includes this header).
//
// Decodes outside input: never throws for any bytes, every problem is an error with
// file:line:col. Real-time contract: not RT-safe (set-up only).
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace rack {

inline constexpr std::size_t kMaxHostFileBytes = 1u << 20;  // larger files are refused unread
inline constexpr std::size_t kMaxHostNesting = 32;          // maps and lists inside each other

struct ConfigError {
  std::string file;
  int line = 0;    // 1-based; 0 when the error is about the whole file
  int column = 0;  // 1-based
  std::string message;
  [[nodiscard]] std::string str() const;  // "file:line:col: message"
};

// The bytes of a host file: nullopt and `error` set when it is not a regular file, is
// larger than kMaxHostFileBytes (fstat before anything is read) or unreadable. Opened
// non-blocking, so a FIFO never stalls the caller.
[[nodiscard]] std::optional<std::string> read_host_bytes(const std::string& path, std::string& error);

// What a tool (rackctl, gdos, a GUI) needs from a host file to join that host's first
// TiMS network: its URL and key file (`tims: networks:`' first entry, else lcm_url,
// else LCM's default multicast group with ttl=0). Reads only those keys.
struct ToolNetwork {
  std::string url;
  std::string key_file;             // "" when the network has none
  std::vector<ConfigError> errors;  // non-empty: unusable (file:line:col)
};
[[nodiscard]] ToolNetwork read_tool_network(const std::string& path);
// The same from text; `file` names it in error messages (the fuzz harnesses' entry).
[[nodiscard]] ToolNetwork read_tool_network_text(const std::string& text, const std::string& file);

}  // namespace rack
