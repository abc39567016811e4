// One network's authentication: received payloads verified and their trailer
// stripped, published ones signed, key files reloaded when they change
// (lcm_transport_auth.h, rack/tims/link_auth.h).
#include "lcm_transport_auth.h"

#include <stdexcept>

#include "lcm_transport_packet.h"
#include "rack/rt/clock.h"
#include "rack_lcm/discover_request.hpp"
#include "rack_lcm/host_announce.hpp"

namespace rack::tims {

using namespace lcm_detail;

LinkAuth::LinkAuth(const NetworkConfig& config, int64_t origin, int64_t replay_window_ns) {
  if (config.key_file.empty()) return;
  try {
    keys_ = std::make_unique<KeyRing>(config.key_file);
  } catch (const std::exception& e) {
    throw std::runtime_error("network '" + config.name + "': " + e.what());
  }
  signer_ = std::make_unique<LinkSigner>(*keys_, origin);
  verifier_ = std::make_unique<LinkVerifier>(*keys_, replay_window_ns);
  scratch_.reserve(4096);
}

bool LinkAuth::accept(std::string_view channel, const uint8_t* d, std::size_t& size, NetworkLog& log) {
  TransportStats& stats = log.stats();
  if (!verifier_) {
    // A signed packet on a network without a key here: this host lacks the key
    // (refused, with a message that says so, instead of half-working on what LCM's
    // decoders would accept). Recognised by a trailer right after the packet's end.
    const auto signed_after = [&](std::size_t end) { return looks_signed(d, size) && end + kAuthTrailerBytes == size; };
    bool is_signed = false;
    if (channel == kTimsChannel) {
      is_signed = size >= kPacketPrefix + kAuthTrailerBytes && signed_after(get_be(d + kOffSize, 4) + kPacketPrefix);
    } else if (channel == kAnnounceChannel) {
      rack_lcm::host_announce a;
      std::string why;
      const int used = looks_signed(d, size) ? wire_lcm::decode(d, size, a, why) : -1;
      is_signed = used > 0 && signed_after(static_cast<std::size_t>(used));
    } else if (channel == kDiscoverChannel) {
      rack_lcm::discover_request r;
      std::string why;
      const int used = looks_signed(d, size) ? wire_lcm::decode(d, size, r, why) : -1;
      is_signed = used > 0 && signed_after(static_cast<std::size_t>(used));
    }
    if (is_signed) {
      bump(stats.malformed);
      bump(channel == kAnnounceChannel   ? stats.malformed_announce
           : channel == kDiscoverChannel ? stats.malformed_discover
                                         : stats.malformed_packet);
      log.warn("unkeyed " + log.name(), [&] {
        return "TiMS/LCM: dropped a signed packet on network '" + log.name() + "' (" + log.url() +
               "), which has no key_file here: give this host the network's key file";
      });
      return false;
    }
    return true;
  }
  const AuthResult r = verifier_->verify(channel, d, size, rt::host_time_ns(), rt::monotonic_ns());
  if (r == AuthResult::kOk) {
    size -= kAuthTrailerBytes;
    return true;
  }
  const bool replay = is_replay(r);
  bump(replay ? stats.replayed : stats.auth_failed);
  const int64_t from = verifier_->last_sender();
  log.warn((replay ? "replayed " : "auth ") + log.name(), [&] {
    return "TiMS/LCM: dropped a packet on network '" + log.name() + "' (" + log.url() + ", key file " + keys_->path() +
           ") channel " + std::string(channel) + (from != 0 ? " from origin " + origin_text(from) : "") + ": " +
           describe(r);
  });
  return false;
}

void LinkAuth::sign(std::string_view channel, uint8_t* buf, std::size_t& len) {
  if (!signer_) return;
  signer_->sign(channel, buf, len, buf + len, rt::host_time_ns());
  len += kAuthTrailerBytes;
}

void LinkAuth::reload(NetworkLog& log) {
  if (!keys_) return;
  const std::string m = keys_->check_reload();
  if (!m.empty()) log.warn("keys " + m, [&] { return "TiMS/LCM: network '" + log.name() + "': " + m; });
}

}  // namespace rack::tims
