// LcmTransport: authenticated links (link_auth.h): received payloads verified and
// their trailer stripped, published ones signed, key files reloaded when they change.
#include "lcm_transport_impl.h"

#include "rack/rt/clock.h"

namespace rack::tims {

using namespace lcm_detail;

// A payload on one of our channels: on a keyed network, verifies and strips its
// trailer (false: dropped, counted, logged); elsewhere, passes it on. Receive threads.
bool LcmTransport::Impl::authentic(Network& n, std::string_view channel, const uint8_t* d, std::size_t& size) {
  if (!n.verifier) {
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
      bump(malformed);
      bump(channel == kAnnounceChannel   ? malformed_announce
           : channel == kDiscoverChannel ? malformed_discover
                                         : malformed_packet);
      warn("unkeyed " + n.config.name, [&] {
        return "TiMS/LCM: dropped a signed packet on network '" + n.config.name + "' (" + n.config.url +
               "), which has no key_file here: give this host the network's key file";
      });
      return false;
    }
    return true;
  }
  const AuthResult r = n.verifier->verify(channel, d, size, rt::host_time_ns(), rt::monotonic_ns());
  if (r == AuthResult::kOk) {
    size -= kAuthTrailerBytes;
    return true;
  }
  const bool replay = is_replay(r);
  bump(replay ? replayed : auth_failed);
  const int64_t from = n.verifier->last_sender();
  warn((replay ? "replayed " : "auth ") + n.config.name, [&] {
    return "TiMS/LCM: dropped a packet on network '" + n.config.name + "' (" + n.config.url + ", key file " +
           n.keys->path() + ") channel " + std::string(channel) +
           (from != 0 ? " from origin " + origin_text(from) : "") + ": " + describe(r);
  });
  return false;
}

// Publishes raw bytes on `n`, signed on a keyed network: `buf` must have
// kAuthTrailerBytes of room after `len`. Caller holds n.publish_mutex.
int LcmTransport::Impl::publish_raw(Network& n, const char* channel, uint8_t* buf, std::size_t len) {
  if (n.signer) {
    n.signer->sign(channel, buf, len, buf + len, rt::host_time_ns());
    len += kAuthTrailerBytes;
  }
  return n.lcm->publish(channel, buf, static_cast<unsigned>(len));
}

// Maintenance thread: re-reads changed key files.
void LcmTransport::Impl::reload_keys() {
  for (auto& n : networks) {
    if (!n->keys) continue;
    const std::string m = n->keys->check_reload();
    if (!m.empty()) warn("keys " + m, [&] { return "TiMS/LCM: network '" + n->config.name + "': " + m; });
  }
}

}  // namespace rack::tims
