// libFuzzer harness for LCM URLs (tims/src/lcm_url.cpp: parse_lcm_url), the text of a
// host file's lcm_url, rackd's and the tools' --lcm and LCM_DEFAULT_URL, checked
// before LCM sees it (LCM 1.3.1 half accepts bad options).
//
// Input: the URL text. Properties: a refusal says why; an accepted URL is at most
// kMaxLcmUrlLength bytes without spaces or control characters, of a known provider,
// and for udpm/mpudpm names a multicast group (224.0.0.0/4), a port 1..65535, a ttl
// 0..255 and a receive buffer of 0 (not given) or 1..2^31-1.
//
// Seeds: tests/fuzz/corpus/lcm_url/ (each provider's form with its keys).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_support.h"
#include "rack/tims/lcm_url.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const rack::tims::LcmUrlResult r = rack::tims::parse_lcm_url(text);
  if (!r.ok()) return 0;
  FUZZ_CHECK(text.size() <= rack::tims::kMaxLcmUrlLength);
  for (const char c : text) FUZZ_CHECK(static_cast<unsigned char>(c) > ' ' && c != 0x7f);
  const auto& u = r.url;
  FUZZ_CHECK(u.provider == "udpm" || u.provider == "mpudpm" || u.provider == "memq" || u.provider == "tcpq" ||
             u.provider == "file");
  if (u.provider == "udpm" || u.provider == "mpudpm") {
    FUZZ_CHECK((u.group >> 28) == 0xE);
    FUZZ_CHECK(u.port >= 1);
    FUZZ_CHECK(u.ttl >= 0 && u.ttl <= 255);
    FUZZ_CHECK(u.recv_buf_size >= 0 && u.recv_buf_size <= 2147483647);
  }
  return 0;
}
