// Authenticated links (rack/tims/link_auth.h): the key file parser and the packet
// trailer check every packet of a keyed network goes through.
//   mode 0: the input as a key file (written mode 0600 to a temporary file, then
//           load_key_file()): refused with a reason, or one or two keys;
//   mode 1: the input as a received payload + trailer on one of the three channels:
//           verify() must refuse what the fuzzer makes up (it cannot forge a MAC);
//   mode 2: the input as payload, trailer fields (sender, sequence, time offset) made
//           from it and the MAC computed with the network key as a sender would
//           (keyed BLAKE2b, as the header documents): verify() must accept a fresh
//           one inside the window, refuse it when replayed, refuse it with a flipped
//           byte, and keep its sender table bounded.
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_support.h"
#include "rack/tims/link_auth.h"

namespace tims = rack::tims;
using rack::fuzz::FuzzInput;

namespace {

constexpr char kKey[] = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
constexpr std::string_view kChannels[] = {"TIMS", "TIMS_ANNOUNCE", "TIMS_DISCOVER"};
constexpr int64_t kWindowNs = tims::kDefaultReplayWindowNs;
constexpr int64_t kNow = 1'700'000'000'000'000'000;

std::string temp_path(const char* what) {
  const char* dir = std::getenv("TMPDIR");
  return std::string(dir != nullptr ? dir : "/tmp") + "/rack_fuzz_link_auth_" + what + "_" + std::to_string(getpid());
}

bool write_file(const std::string& path, const uint8_t* data, std::size_t size) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  const bool ok = size == 0 || std::fwrite(data, 1, size, f) == size;
  std::fclose(f);
  chmod(path.c_str(), 0600);
  return ok;
}

// The network key every verifying input is checked against.
struct Network {
  std::string path = temp_path("key");
  tims::KeyRing* ring = nullptr;
  tims::LinkKey key;
  Network() {
    const std::string text = std::string(kKey) + "\n";
    FUZZ_CHECK(write_file(path, reinterpret_cast<const uint8_t*>(text.data()), text.size()));
    ring = new tims::KeyRing(path);  // lives as long as the process
    const tims::KeyFile f = tims::load_key_file(path);
    FUZZ_CHECK(f.error.empty() && f.keys.size() == 1);
    key = f.keys[0];
    unlink(path.c_str());
  }
};
Network& network() {
  static Network n;
  return n;
}

void put_be64(uint8_t* p, uint64_t v) {
  for (int i = 7; i >= 0; --i, v >>= 8) p[i] = static_cast<uint8_t>(v);
}

void sign(const tims::LinkKey& key, std::string_view channel, std::vector<uint8_t>& packet, int64_t sender,
          uint64_t seq, int64_t time) {
  const std::size_t payload = packet.size();
  packet.resize(payload + tims::kAuthTrailerBytes);
  uint8_t* t = packet.data() + payload;
  std::memcpy(t, "RKA1", 4);
  for (int i = 0; i < 4; ++i) t[4 + i] = static_cast<uint8_t>(key.id >> (24 - 8 * i));
  put_be64(t + 8, static_cast<uint64_t>(sender));
  put_be64(t + 16, seq);
  put_be64(t + 24, static_cast<uint64_t>(time));
  crypto_generichash_state st;
  crypto_generichash_init(&st, key.bytes.data(), key.bytes.size(), 16);
  const uint8_t nul = 0;
  crypto_generichash_update(&st, reinterpret_cast<const unsigned char*>(channel.data()), channel.size());
  crypto_generichash_update(&st, &nul, 1);
  crypto_generichash_update(&st, packet.data(), payload);
  crypto_generichash_update(&st, t, 32);
  crypto_generichash_final(&st, t + 32, 16);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  FuzzInput in(data, size);
  const uint8_t mode = in.byte() % 3;
  const std::string_view channel = kChannels[in.byte() % 3];
  Network& net = network();
  if (mode == 0) {
    static const std::string path = temp_path("file");
    const auto text = in.rest();
    FUZZ_CHECK(write_file(path, text.data(), text.size()));
    const tims::KeyFile f = tims::load_key_file(path);
    FUZZ_CHECK(f.error.empty() != f.keys.empty());
    FUZZ_CHECK(f.keys.size() <= 2);
    unlink(path.c_str());
    return 0;
  }
  tims::LinkVerifier verifier(*net.ring, kWindowNs);
  if (mode == 1) {
    const auto packet = in.rest();
    const auto r = verifier.verify(channel, packet.data(), packet.size(), kNow, 1);
    FUZZ_CHECK(r != tims::AuthResult::kOk);
    FUZZ_CHECK(tims::describe(r) != nullptr);
    return 0;
  }
  // mode 2: packets signed here, several senders and sequence numbers from the input.
  int64_t mono = 1;
  while (in.remaining() >= 4) {
    const auto sender = static_cast<int64_t>(in.byte() % 8 + 1) * 0x0101010101LL;
    const uint64_t seq = in.take<uint16_t>();
    const auto skew = static_cast<int64_t>(static_cast<int8_t>(in.byte())) * 100'000'000;  // +-12.8 s
    std::vector<uint8_t> packet;
    const auto body = in.bytes(in.byte() % 32);
    packet.assign(body.begin(), body.end());
    sign(net.key, channel, packet, sender, seq, kNow + skew);
    const auto r = verifier.verify(channel, packet.data(), packet.size(), kNow, mono);
    const bool inside = skew >= -kWindowNs && skew <= kWindowNs;
    if (!inside) FUZZ_CHECK(r == tims::AuthResult::kOutsideWindow);
    if (r == tims::AuthResult::kOk) {
      FUZZ_CHECK(verifier.verify(channel, packet.data(), packet.size(), kNow, mono) == tims::AuthResult::kReplayed);
    }
    packet[packet.size() / 2] ^= 0x01;
    FUZZ_CHECK(verifier.verify(channel, packet.data(), packet.size(), kNow, mono) != tims::AuthResult::kOk);
    mono += 1'000'000;
  }
  return 0;
}
