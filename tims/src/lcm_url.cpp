#include "rack/tims/lcm_url.h"

#include <arpa/inet.h>

#include <set>

namespace rack::tims {

namespace {

// Digits only (no sign, no spaces, no hex), at most 18 of them: no overflow.
bool parse_uint(std::string_view s, int64_t max, int64_t& out) {
  if (s.empty() || s.size() > 18) return false;
  int64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  if (v > max) return false;
  out = v;
  return true;
}

std::string quoted(std::string_view s) {
  std::string q(1, '\'');
  q.append(s);
  q.push_back('\'');
  return q;
}

bool host_char(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '-' || c == '_';
}

}  // namespace

LcmUrlResult parse_lcm_url(std::string_view text) {
  LcmUrlResult r;
  auto fail = [&](std::string why) {
    r.error = std::move(why);
    return r;
  };
  if (text.empty()) return fail("an LCM URL must not be empty (e.g. udpm://239.255.76.67:7667?ttl=0)");
  if (text.size() > kMaxLcmUrlLength) {
    return fail("an LCM URL has at most " + std::to_string(kMaxLcmUrlLength) + " characters, this one " +
                std::to_string(text.size()));
  }
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c <= 0x20 || c >= 0x7f) {
      return fail("an LCM URL holds printable ASCII only, without spaces (character " + std::to_string(i + 1) +
                  " is byte " + std::to_string(c) + ")");
    }
  }
  const std::size_t sep = text.find("://");
  if (sep == std::string_view::npos || sep == 0) {
    return fail(quoted(text) + " is not an LCM URL (provider://network?options, e.g. udpm://239.255.76.67:7667?ttl=0)");
  }
  r.url.provider = std::string(text.substr(0, sep));
  std::string_view rest = text.substr(sep + 3);
  std::string_view options;
  bool have_options = false;
  if (const auto q = rest.find('?'); q != std::string_view::npos) {
    options = rest.substr(q + 1);
    rest = rest.substr(0, q);
    have_options = true;
  }
  r.url.network = std::string(rest);
  const std::string& p = r.url.provider;
  std::set<std::string> allowed;
  if (p == "udpm" || p == "mpudpm") {
    allowed = {"ttl", "recv_buf_size"};
    std::string_view group = rest;
    r.url.port = 7667;
    if (const auto colon = rest.find(':'); colon != std::string_view::npos) {
      group = rest.substr(0, colon);
      int64_t port = 0;
      if (!parse_uint(rest.substr(colon + 1), 65535, port) || port == 0) {
        return fail("port " + quoted(rest.substr(colon + 1)) + " of " + quoted(text) + " is not a number 1..65535");
      }
      r.url.port = static_cast<uint16_t>(port);
    }
    if (group.empty()) group = "239.255.76.67";
    in_addr a{};
    const std::string g(group);
    if (inet_pton(AF_INET, g.c_str(), &a) != 1) {
      return fail("group " + quoted(group) + " of " + quoted(text) + " is not an IPv4 address (e.g. 239.255.76.67)");
    }
    r.url.group = ntohl(a.s_addr);
    if ((r.url.group >> 28) != 0xE) {
      return fail("group " + quoted(group) + " of " + quoted(text) + " is not a multicast address (224.0.0.0/4)");
    }
  } else if (p == "memq") {
    if (!rest.empty()) return fail("memq:// takes no network (" + quoted(text) + ")");
  } else if (p == "tcpq") {
    std::string_view host = rest;
    if (const auto colon = rest.find(':'); colon != std::string_view::npos) {
      host = rest.substr(0, colon);
      int64_t port = 0;
      if (!parse_uint(rest.substr(colon + 1), 65535, port) || port == 0) {
        return fail("port " + quoted(rest.substr(colon + 1)) + " of " + quoted(text) + " is not a number 1..65535");
      }
      r.url.port = static_cast<uint16_t>(port);
    }
    if (host.empty()) return fail("tcpq:// needs a server: tcpq://HOST:PORT (" + quoted(text) + ")");
    for (char c : host) {
      if (!host_char(c)) return fail("server " + quoted(host) + " of " + quoted(text) + " is not a host name");
    }
  } else if (p == "file") {
    allowed = {"mode", "speed", "start_timestamp"};
    if (rest.empty()) return fail("file:// needs a path: file:///var/log/robot.lcm?mode=r (" + quoted(text) + ")");
  } else {
    return fail("unknown LCM provider " + quoted(p) + " in " + quoted(text) + " (udpm, mpudpm, memq, tcpq, file)");
  }
  if (have_options && options.empty()) return fail(quoted(text) + " ends in '?' without options");
  std::set<std::string> seen;
  while (!options.empty()) {
    const std::size_t amp = options.find('&');
    const std::string_view kv = options.substr(0, amp);
    options = amp == std::string_view::npos ? std::string_view() : options.substr(amp + 1);
    if (amp != std::string_view::npos && options.empty()) return fail(quoted(text) + " ends in '&'");
    const std::size_t eq = kv.find('=');
    if (eq == std::string_view::npos || eq == 0) {
      return fail("option " + quoted(kv) + " of " + quoted(text) + " is not key=value");
    }
    const std::string key(kv.substr(0, eq));
    const std::string_view value = kv.substr(eq + 1);
    if (allowed.count(key) == 0) {
      std::string list;
      for (const auto& k : allowed) list += (list.empty() ? "" : ", ") + k;
      return fail("unknown option " + quoted(key) + " for " + p + ":// in " + quoted(text) +
                  (list.empty() ? " (it takes none)" : " (known: " + list + ")"));
    }
    if (!seen.insert(key).second) return fail("option " + quoted(key) + " given twice in " + quoted(text));
    int64_t v = 0;
    if (key == "ttl") {
      if (!parse_uint(value, 255, v)) return fail("ttl " + quoted(value) + " of " + quoted(text) + " is not 0..255");
      r.url.ttl = static_cast<int>(v);
    } else if (key == "recv_buf_size") {
      if (!parse_uint(value, 2147483647, v) || v == 0) {
        return fail("recv_buf_size " + quoted(value) + " of " + quoted(text) + " is not a byte count 1..2147483647");
      }
      r.url.recv_buf_size = v;
    } else if (key == "mode") {
      if (value != "r" && value != "w" && value != "a") {
        return fail("mode " + quoted(value) + " of " + quoted(text) + " is not r, w or a");
      }
    } else if (key == "speed" || key == "start_timestamp") {
      // Decimal digits with at most one '.', as LCM's strtod reads them.
      int dots = 0, digits = 0, other = 0;
      for (char c : value) (c == '.' ? dots : (c >= '0' && c <= '9') ? digits : other) += 1;
      if (other != 0 || digits == 0 || dots > 1) {
        return fail(key + " " + quoted(value) + " of " + quoted(text) + " is not a non-negative number");
      }
    }
  }
  return r;
}

}  // namespace rack::tims
