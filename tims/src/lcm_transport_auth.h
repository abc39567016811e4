// One network's authentication (internal to tims): the glue between the transport and
// rack/tims/link_auth.h. On a network with a key file it holds the keys, signs what
// the network publishes and verifies (and strips the trailer of) what it receives; on
// a network without one it refuses, with a message that says so, packets that carry a
// trailer (this host lacks the key).
//
// Real-time contract: nothing here is RT-safe (the transport's non-RT threads).
// Thread-safety: sign() and encode() under the network's publish lock; accept() on its
// receive thread; reload() on the maintenance thread (KeyRing locks).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <vector>

#include "lcm_transport_stats.h"
#include "rack/tims/link_auth.h"

namespace rack::tims {

class LinkAuth {
 public:
  // Reads `config.key_file` when it names one; throws std::runtime_error naming the
  // network and the reason when it is refused. `origin`: this transport's (the signer's
  // sender id); `replay_window_ns`: LcmTransportConfig's.
  LinkAuth(const NetworkConfig& config, int64_t origin, int64_t replay_window_ns);

  [[nodiscard]] bool keyed() const noexcept { return keys_ != nullptr; }
  // Bytes a published packet needs after its end (its trailer), 0 without a key.
  [[nodiscard]] std::size_t trailer_bytes() const noexcept { return keyed() ? kAuthTrailerBytes : 0; }

  // A payload received on one of our channels: on a keyed network, verifies it and
  // strips its trailer from `size`; elsewhere, refuses one that looks signed. False:
  // dropped (counted in `log`'s counters: auth_failed, replayed or malformed; said).
  bool accept(std::string_view channel, const uint8_t* d, std::size_t& size, NetworkLog& log);
  // Appends the trailer to `len` bytes at `buf` (room for trailer_bytes() after them)
  // and grows `len`; nothing without a key.
  void sign(std::string_view channel, uint8_t* buf, std::size_t& len);
  // An lcm-gen message encoded into the scratch buffer with room for its trailer
  // (keyed networks publish typed messages as raw bytes); empty when it cannot encode.
  template <typename T>
  std::span<uint8_t> encode(const T& m) {
    const int size = m.getEncodedSize();
    if (size < 0) return {};
    scratch_.resize(static_cast<std::size_t>(size) + kAuthTrailerBytes);
    if (m.encode(scratch_.data(), 0, size) != size) return {};
    return {scratch_.data(), static_cast<std::size_t>(size)};
  }
  // Re-reads a changed key file (said through `log` when it did or was refused).
  void reload(NetworkLog& log);

 private:
  std::unique_ptr<KeyRing> keys_;
  std::unique_ptr<LinkSigner> signer_;
  std::unique_ptr<LinkVerifier> verifier_;
  std::vector<uint8_t> scratch_;  // encoded typed messages + trailer
};

}  // namespace rack::tims
