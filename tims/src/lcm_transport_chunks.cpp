// LcmTransport: a TiMS message on the wire: cut into tims_packet chunks below LCM's
// fragmentation size, its body compressed (zstd) where the network asks for it, and
// put together again on receipt in preallocated reassembly slots.
#include "lcm_transport_impl.h"

#include <zstd.h>

#include <algorithm>

#include "rack/rt/clock.h"

namespace rack::tims {

using namespace lcm_detail;

// Publishes one TiMS message (host byte order header at the start) on `n`, chunked
// and compressed as the network says. `writable`: the caller owns `msg` and lets it
// be used as scratch (restored before return), so that chunks after the first go out
// in place (the 50-byte prefix written over the tail of the chunk before, which has
// been sent) instead of being copied into the packet buffer first. Any non-RT thread.
bool LcmTransport::Impl::publish_message(Network& n, const std::byte* msg, uint32_t len, int64_t msg_origin,
                                         int64_t relay, int8_t hops, int32_t seq, bool writable) {
  std::lock_guard lock(n.publish_mutex);
  const std::byte* stream = msg;
  uint32_t encoded = len;
  int8_t encoding = 0;
  if (n.cctx != nullptr && len >= n.config.compress_min_bytes) {
    // Encoding 2: the 16-byte header as it is, then the body as one zstd frame. Every
    // host reads the destination from the first chunk and drops the rest of a message
    // for another host unread (encoding 1, the whole message compressed, made every
    // host on the network reassemble and decompress every compressed message).
    constexpr std::size_t kHead = sizeof(MessageHeader);
    const std::size_t c = ZSTD_compressCCtx(n.cctx, n.compressed.data() + kHead, n.compressed.size() - kHead,
                                            msg + kHead, len - kHead, 1);
    if (ZSTD_isError(c) == 0 && kHead + c < len) {
      std::memcpy(n.compressed.data(), msg, kHead);
      stream = n.compressed.data();
      encoded = static_cast<uint32_t>(kHead + c);
      encoding = 2;
      writable = true;  // our own buffer
      bump(compressed_out);
    }
  }
  bool ok = true;
  for (uint32_t off = 0; off < encoded; off += kChunk) {
    const uint32_t size = std::min(kChunk, encoded - off);
    // Signed packets get a trailer after the chunk: built in the packet buffer.
    const bool in_place = writable && off >= kPacketPrefix && !n.signer;
    std::array<uint8_t, kPacketPrefix> saved{};
    uint8_t* p = nullptr;
    if (in_place) {
      // const_cast: `writable` says the caller owns this memory exclusively.
      p = reinterpret_cast<uint8_t*>(const_cast<std::byte*>(stream + off - kPacketPrefix));
      std::memcpy(saved.data(), p, kPacketPrefix);
    } else {
      p = n.packet.data();
      std::memcpy(p + kPacketPrefix, stream + off, size);
    }
    put_be(p, static_cast<uint64_t>(rack_lcm::tims_packet::getHash()), 8);
    put_be(p + kOffOrigin, static_cast<uint64_t>(msg_origin), 8);
    put_be(p + kOffRelay, static_cast<uint64_t>(relay), 8);
    put_be(p + kOffPacketSeq, ++n.packet_seq, 4);
    put_be(p + kOffMessageSeq, static_cast<uint32_t>(seq), 4);
    put_be(p + kOffTotal, len, 4);
    put_be(p + kOffEncoded, encoded, 4);
    put_be(p + kOffOffset, off, 4);
    p[kOffEncoding] = static_cast<uint8_t>(encoding);
    p[kOffHops] = static_cast<uint8_t>(hops);
    put_be(p + kOffSize, size, 4);
    const int rc = publish_raw(n, kTimsChannel, p, kPacketPrefix + size);
    if (in_place) std::memcpy(p, saved.data(), kPacketPrefix);
    if (rc != 0) {
      bump(publish_errors);
      ok = false;
      warn("publish", [&] { return "TiMS/LCM: publish on " + n.config.url + " failed"; });
      break;
    }
    bump(packets_out);
  }
  if (ok) {
    bump(messages_out);
    bump(bytes_out, len);
    bump(wire_bytes_out, encoded);
  }
  return ok;
}

void LcmTransport::Impl::count_gap(Network& n, int64_t publisher, uint32_t seq) {
  if (n.last_packet_seq.size() > 4096) n.last_packet_seq.clear();  // bounded; a restart of counting
  auto [it, fresh] = n.last_packet_seq.try_emplace(publisher, seq);
  if (fresh) return;
  const uint32_t expected = it->second + 1;
  const uint32_t ahead = seq - expected;  // modulo 2^32
  if (ahead != 0 && ahead < (1u << 20)) bump(sequence_gaps, ahead);
  if (ahead < (1u << 31)) it->second = seq;  // ignore late (reordered) packets
}

void LcmTransport::Impl::report_lost(Network& n, Reassembly& s, const char* why) {
  bump(lost_messages);
  std::string what = "message " + std::to_string(s.message_seq) + " of origin " + origin_text(s.origin);
  if (s.have[0] != 0 && s.encoding != 1 && s.total >= sizeof(MessageHeader)) {
    MessageHeader h;
    if (decode_header(std::span<const std::byte>(s.data.data(), s.total), h) != MessageError::kOk) {
      // decode_header checks the length too, which is the full one here: read raw.
      std::memcpy(&h, s.data.data(), sizeof h);
    }
    what = "message from " + h.source().str() + " to " + h.destination().str();
  }
  const uint32_t received = s.received;
  const uint32_t chunks = s.chunks;
  const uint32_t total = s.total;
  warn("lost", [&] {
    return "TiMS/LCM: " + what + " (" + std::to_string(total) + " bytes) lost on network '" + n.config.name +
           "': " + std::to_string(chunks - received) + " of " + std::to_string(chunks) + " chunks missing (" + why +
           "); raise recv_buf_size in the LCM URL and net.core.rmem_max";
  });
  s.used = false;
}

void LcmTransport::Impl::expire_reassembly(Network& n) {
  const int64_t now = rt::monotonic_ns();
  for (auto& s : n.slots) {
    if (s.used && now - s.started_ns > config.reassembly_timeout_ns) report_lost(n, s, "timed out");
  }
}

// A whole datagram's tims_packet (from LCM, or read whole from our socket).
void LcmTransport::Impl::on_packet(Network& n, const uint8_t* d, std::size_t size, const std::string& channel) {
  const ChunkPlan plan = plan_chunk(n, d, size, channel);
  if (plan.kind == ChunkPlan::kSingle) {
    const int32_t total = get_i32(d + kOffTotal);
    return take_stream(n, reinterpret_cast<const std::byte*>(d + kPacketPrefix), false, plan.size,
                       static_cast<uint32_t>(total), static_cast<int8_t>(d[kOffEncoding]), get_i64(d + kOffOrigin),
                       get_i32(d + kOffMessageSeq), static_cast<int8_t>(d[kOffHops]));
  }
  if (plan.kind != ChunkPlan::kSlot) return;
  std::memcpy(plan.slot->data.data() + plan.offset, d + kPacketPrefix, plan.size);
  finish_chunk(n, *plan.slot);
}

// Validates a tims_packet of `size` bytes of which the prefix and, for a first chunk,
// the message header are at `d` (the rest of the chunk may still be in the socket),
// and says where its bytes go. A chunk planned into a slot is marked received there:
// the caller copies it and calls finish_chunk().
LcmTransport::Impl::ChunkPlan LcmTransport::Impl::plan_chunk(Network& n, const uint8_t* d, std::size_t size,
                                                             const std::string& channel) {
  bump(packets_in);
  if (size < kPacketPrefix) {
    return rejected(n, "short", [&] {
      return "'" + channel + "': " + std::to_string(size) + " bytes, shorter than a tims_packet";
    });
  }
  if (get_be(d, 8) != static_cast<uint64_t>(rack_lcm::tims_packet::getHash())) {
    return rejected(n, "type", [&] { return "'" + channel + "': not a rack_lcm.tims_packet (fingerprint differs)"; });
  }
  const int64_t pkt_origin = get_i64(d + kOffOrigin);
  const int64_t relay = get_i64(d + kOffRelay);
  const auto pseq = static_cast<uint32_t>(get_i32(d + kOffPacketSeq));
  const int32_t mseq = get_i32(d + kOffMessageSeq);
  const int32_t total = get_i32(d + kOffTotal);
  const int32_t encoded = get_i32(d + kOffEncoded);
  const int32_t offset = get_i32(d + kOffOffset);
  const auto encoding = static_cast<int8_t>(d[kOffEncoding]);
  const auto hops = static_cast<int8_t>(d[kOffHops]);
  const int32_t chunk = get_i32(d + kOffSize);
  if (static_cast<int64_t>(chunk) != static_cast<int64_t>(size - kPacketPrefix)) {
    return rejected(n, "size", [&] {
      return "size field " + std::to_string(chunk) + " but " + std::to_string(size - kPacketPrefix) + " bytes follow";
    });
  }
  if (pkt_origin == origin || relay == origin) return {};  // our own packet, back over multicast
  count_gap(n, relay != 0 ? relay : pkt_origin, pseq);
  const uint32_t max_encoded = static_cast<uint32_t>(n.slots[0].data.size());
  if (total < static_cast<int32_t>(sizeof(MessageHeader)) || static_cast<uint32_t>(total) > config.max_message_bytes ||
      encoded < 0 || static_cast<uint32_t>(encoded) > max_encoded || offset < 0 ||
      static_cast<uint32_t>(offset) % kChunk != 0 || static_cast<int64_t>(offset) + chunk > encoded ||
      (static_cast<int64_t>(offset) + chunk != encoded && static_cast<uint32_t>(chunk) != kChunk) || encoding < 0 ||
      encoding > 2 || (encoding == 0 && encoded != total) ||
      (encoding == 2 && encoded <= static_cast<int32_t>(sizeof(MessageHeader))) || hops < 0 || hops > kMaxHops) {
    return rejected(n, "fields", [&] {
      return "bad chunk fields (total " + std::to_string(total) + ", encoded " + std::to_string(encoded) + ", offset " +
             std::to_string(offset) + ", size " + std::to_string(chunk) + ", encoding " + std::to_string(encoding) +
             ", hops " + std::to_string(hops) + ", limit " + std::to_string(config.max_message_bytes) + " bytes)";
    });
  }
  const auto* data = reinterpret_cast<const std::byte*>(d + kPacketPrefix);
  if (offset == 0 && chunk == encoded) {  // one chunk: the common case
    return {ChunkPlan::kSingle, nullptr, 0, static_cast<uint32_t>(chunk)};
  }
  for (const auto& k : n.skipped) {
    if (k.first == pkt_origin && k.second == mseq && pkt_origin != 0) return {};
  }
  Reassembly* slot = nullptr;
  for (auto& s : n.slots) {
    if (s.used && s.origin == pkt_origin && s.message_seq == mseq) slot = &s;
  }
  if (offset == 0 && encoding != 1 && !wants(data, static_cast<std::size_t>(chunk))) {
    bump(not_for_us);
    n.skipped[n.next_skipped] = {pkt_origin, mseq};
    n.next_skipped = (n.next_skipped + 1) % n.skipped.size();
    if (slot != nullptr) slot->used = false;  // chunks that came before the first
    return {};
  }
  if (slot == nullptr) {
    for (auto& s : n.slots) {
      if (!s.used) {
        slot = &s;
        break;
      }
    }
    if (slot == nullptr) {  // all busy: the oldest gives way
      slot = &n.slots[0];
      for (auto& s : n.slots) {
        if (s.started_ns < slot->started_ns) slot = &s;
      }
      report_lost(n, *slot, "displaced by newer messages");
    }
    slot->used = true;
    slot->origin = pkt_origin;
    slot->message_seq = mseq;
    slot->total = static_cast<uint32_t>(total);
    slot->encoded = static_cast<uint32_t>(encoded);
    slot->encoding = encoding;
    slot->hops = hops;
    slot->chunks = (static_cast<uint32_t>(encoded) + kChunk - 1) / kChunk;
    slot->received = 0;
    slot->started_ns = rt::monotonic_ns();
    std::fill(slot->have.begin(), slot->have.end(), 0);
  } else if (slot->total != static_cast<uint32_t>(total) || slot->encoded != static_cast<uint32_t>(encoded) ||
             slot->encoding != encoding) {
    reject(n, "chunk", [&] { return std::string("a chunk disagrees with its message's first chunk"); });
    return {};
  }
  const uint32_t index = static_cast<uint32_t>(offset) / kChunk;
  if (index >= slot->have.size()) {  // cannot happen after the checks above; belt and braces
    reject(n, "chunk", [&] { return "chunk index " + std::to_string(index) + " out of range"; });
    return {};
  }
  if (slot->have[index] != 0) return {};  // duplicate
  slot->have[index] = 1;
  ++slot->received;
  return {ChunkPlan::kSlot, slot, static_cast<uint32_t>(offset), static_cast<uint32_t>(chunk)};
}

LcmTransport::Impl::ChunkPlan LcmTransport::Impl::rejected(Network& n, const std::string& kind,
                                                           const std::function<std::string()>& why) {
  reject(n, kind, why);
  return {};
}

// A chunk's bytes are in its slot: hands the message on when it is complete.
void LcmTransport::Impl::finish_chunk(Network& n, Reassembly& slot) {
  if (slot.received != slot.chunks) return;
  slot.used = false;
  take_stream(n, slot.data.data(), true, slot.encoded, slot.total, slot.encoding, slot.origin, slot.message_seq,
              slot.hops);
}

// A planned chunk that did not arrive after all (the socket read failed): the slot
// waits for it again, as for a lost datagram.
void LcmTransport::Impl::unplan_chunk(Reassembly& slot, uint32_t offset) {
  slot.have[offset / kChunk] = 0;
  --slot.received;
}

// A whole encoded message: decode it (into n.message, or in place when `stream` is
// our own reassembly buffer: a 4 MiB message is not copied once more), then handle it.
void LcmTransport::Impl::take_stream(Network& n, const std::byte* stream, bool own_buffer, uint32_t encoded,
                                     uint32_t total, int8_t encoding, int64_t msg_origin, int32_t mseq, int8_t hops) {
  if (encoding == 1) {
    const unsigned long long size = ZSTD_getFrameContentSize(stream, encoded);
    if (size != total) {
      return reject(n, "zstd",
                    [&] { return std::string("compressed message whose frame size differs from its total"); });
    }
    const std::size_t got = ZSTD_decompressDCtx(n.dctx, n.message.data(), total, stream, encoded);
    if (ZSTD_isError(got) != 0 || got != total) {
      return reject(n, "zstd", [&] {
        return std::string("compressed message does not decompress: ") +
               (ZSTD_isError(got) != 0 ? ZSTD_getErrorName(got) : "wrong size");
      });
    }
  } else if (encoding == 2) {
    // The header as it is, then the body's frame (encoded > 16: checked on receipt).
    constexpr std::size_t kHead = sizeof(MessageHeader);
    if (!wants(stream, encoded)) {  // a one-chunk message for another host: not decompressed
      bump(not_for_us);
      return;
    }
    const std::size_t body = total - kHead;
    const unsigned long long size = ZSTD_getFrameContentSize(stream + kHead, encoded - kHead);
    if (total < kHead || size != body) {
      return reject(n, "zstd", [&] { return std::string("compressed body whose frame size differs from its total"); });
    }
    std::memcpy(n.message.data(), stream, kHead);
    const std::size_t got = ZSTD_decompressDCtx(n.dctx, n.message.data() + kHead, body, stream + kHead,
                                                encoded - kHead);
    if (ZSTD_isError(got) != 0 || got != body) {
      return reject(n, "zstd", [&] {
        return std::string("compressed body does not decompress: ") +
               (ZSTD_isError(got) != 0 ? ZSTD_getErrorName(got) : "wrong size");
      });
    }
  } else if (own_buffer) {
    return handle_message(n, const_cast<std::byte*>(stream), total, msg_origin, mseq, hops);
  } else {
    std::memcpy(n.message.data(), stream, total);
  }
  handle_message(n, n.message.data(), total, msg_origin, mseq, hops);
}

}  // namespace rack::tims
