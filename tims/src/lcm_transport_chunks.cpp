// A TiMS message on the wire: cut into tims_packet chunks, its body compressed (zstd)
// where the network asks for it, and put together again on receipt in preallocated
// reassembly slots (lcm_transport_chunks.h).
#include "lcm_transport_chunks.h"

#include <algorithm>

#include "lcm_transport_packet.h"
#include "rack/rt/clock.h"
#include "rack/tims/message.h"
#include "rack_lcm/tims_packet.hpp"

namespace rack::tims {

using namespace lcm_detail;

ChunkPublisher::ChunkPublisher(const NetworkConfig& config, uint32_t max_message_bytes, std::size_t trailer_bytes,
                               NetworkLog& log)
    : log_(log), compress_min_bytes_(config.compress_min_bytes), trailer_bytes_(trailer_bytes) {
  packet_.assign(kPacketPrefix + kChunk + trailer_bytes_, 0);
  put_be(packet_.data(), static_cast<uint64_t>(rack_lcm::tims_packet::getHash()), 8);
  if (config.compression == Compression::kZstd) {
    compressed_.resize(ZSTD_compressBound(max_message_bytes));
    cctx_ = ZSTD_createCCtx();
  }
}

ChunkPublisher::~ChunkPublisher() {
  if (cctx_ != nullptr) ZSTD_freeCCtx(cctx_);
}

bool ChunkPublisher::publish(const std::byte* msg, uint32_t len, int64_t origin, int64_t relay, int8_t hops,
                             int32_t seq, bool writable, PacketOut& out) {
  TransportStats& stats = log_.stats();
  const std::byte* stream = msg;
  uint32_t encoded = len;
  int8_t encoding = 0;
  if (cctx_ != nullptr && len >= compress_min_bytes_) {
    // Encoding 2: the 16-byte header as it is, then the body as one zstd frame. Every
    // host reads the destination from the first chunk and drops the rest of a message
    // for another host unread (encoding 1, the whole message compressed, made every
    // host on the network reassemble and decompress every compressed message).
    constexpr std::size_t kHead = sizeof(MessageHeader);
    const std::size_t c = ZSTD_compressCCtx(cctx_, compressed_.data() + kHead, compressed_.size() - kHead, msg + kHead,
                                            len - kHead, 1);
    if (ZSTD_isError(c) == 0 && kHead + c < len) {
      std::memcpy(compressed_.data(), msg, kHead);
      stream = compressed_.data();
      encoded = static_cast<uint32_t>(kHead + c);
      encoding = 2;
      writable = true;  // our own buffer
      bump(stats.compressed_out);
    }
  }
  bool ok = true;
  for (uint32_t off = 0; off < encoded; off += kChunk) {
    const uint32_t size = std::min(kChunk, encoded - off);
    // Signed packets get a trailer after the chunk: built in the packet buffer.
    const bool in_place = writable && off >= kPacketPrefix && trailer_bytes_ == 0;
    std::array<uint8_t, kPacketPrefix> saved{};
    uint8_t* p = nullptr;
    if (in_place) {
      // const_cast: `writable` says the caller owns this memory exclusively.
      p = reinterpret_cast<uint8_t*>(const_cast<std::byte*>(stream + off - kPacketPrefix));
      std::memcpy(saved.data(), p, kPacketPrefix);
    } else {
      p = packet_.data();
      std::memcpy(p + kPacketPrefix, stream + off, size);
    }
    put_be(p, static_cast<uint64_t>(rack_lcm::tims_packet::getHash()), 8);
    put_be(p + kOffOrigin, static_cast<uint64_t>(origin), 8);
    put_be(p + kOffRelay, static_cast<uint64_t>(relay), 8);
    put_be(p + kOffPacketSeq, ++packet_seq_, 4);
    put_be(p + kOffMessageSeq, static_cast<uint32_t>(seq), 4);
    put_be(p + kOffTotal, len, 4);
    put_be(p + kOffEncoded, encoded, 4);
    put_be(p + kOffOffset, off, 4);
    p[kOffEncoding] = static_cast<uint8_t>(encoding);
    p[kOffHops] = static_cast<uint8_t>(hops);
    put_be(p + kOffSize, size, 4);
    const int rc = out.send_packet(p, kPacketPrefix + size);
    if (in_place) std::memcpy(p, saved.data(), kPacketPrefix);
    if (rc != 0) {
      bump(stats.publish_errors);
      ok = false;
      log_.warn("publish", [&] { return "TiMS/LCM: publish on " + log_.url() + " failed"; });
      break;
    }
    bump(stats.packets_out);
  }
  if (ok) {
    bump(stats.messages_out);
    bump(stats.bytes_out, len);
    bump(stats.wire_bytes_out, encoded);
  }
  return ok;
}

ChunkReassembler::ChunkReassembler(int64_t own_origin, const ChunkLimits& limits, NetworkLog& log, MessageSink& sink)
    : own_origin_(own_origin), limits_(limits), log_(log), sink_(sink) {
  dctx_ = ZSTD_createDCtx();
  message_.resize(limits_.max_message_bytes);
  slots_.resize(std::max<uint32_t>(limits_.slots, 1));
  const uint32_t max_chunks = (limits_.max_message_bytes + kChunk - 1) / kChunk + 1;
  // Compressed streams can exceed the message a little (incompressible data).
  const std::size_t max_encoded = ZSTD_compressBound(limits_.max_message_bytes);
  for (auto& s : slots_) {
    s.data.resize(max_encoded);
    s.have.resize(max_chunks + 1);
  }
}

ChunkReassembler::~ChunkReassembler() {
  if (dctx_ != nullptr) ZSTD_freeDCtx(dctx_);
}

void ChunkReassembler::count_gap(int64_t publisher, uint32_t seq) {
  if (last_packet_seq_.size() > 4096) last_packet_seq_.clear();  // bounded; a restart of counting
  auto [it, fresh] = last_packet_seq_.try_emplace(publisher, seq);
  if (fresh) return;
  const uint32_t expected = it->second + 1;
  const uint32_t ahead = seq - expected;  // modulo 2^32
  if (ahead != 0 && ahead < (1u << 20)) bump(log_.stats().sequence_gaps, ahead);
  if (ahead < (1u << 31)) it->second = seq;  // ignore late (reordered) packets
}

void ChunkReassembler::report_lost(Slot& s, const char* why) {
  bump(log_.stats().lost_messages);
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
  log_.warn("lost", [&] {
    return "TiMS/LCM: " + what + " (" + std::to_string(total) + " bytes) lost on network '" + log_.name() +
           "': " + std::to_string(chunks - received) + " of " + std::to_string(chunks) + " chunks missing (" + why +
           "); raise recv_buf_size in the LCM URL and net.core.rmem_max";
  });
  s.used = false;
}

void ChunkReassembler::expire(int64_t now_ns) {
  for (auto& s : slots_) {
    if (s.used && now_ns - s.started_ns > limits_.timeout_ns) report_lost(s, "timed out");
  }
}

void ChunkReassembler::on_packet(const uint8_t* d, std::size_t size, std::string_view channel) {
  const Plan p = plan(d, size, channel);
  if (p.kind == Plan::kSingle) return take_single(d, size);
  if (p.kind != Plan::kSlot) return;
  std::memcpy(p.into, d + kPacketPrefix, p.size);
  finish(p);
}

ChunkReassembler::Plan ChunkReassembler::plan(const uint8_t* d, std::size_t size, std::string_view channel) {
  TransportStats& stats = log_.stats();
  bump(stats.packets_in);
  // 'CHANNEL': (appended, not `"'" + std::string(channel)`: GCC 12 warns, -Wrestrict, on
  // that form).
  const auto on_channel = [&] {
    std::string text = "'";
    text += channel;
    text += "': ";
    return text;
  };
  if (size < kPacketPrefix) {
    return rejected("short",
                    [&] { return on_channel() + std::to_string(size) + " bytes, shorter than a tims_packet"; });
  }
  if (get_be(d, 8) != static_cast<uint64_t>(rack_lcm::tims_packet::getHash())) {
    return rejected("type", [&] { return on_channel() + "not a rack_lcm.tims_packet (fingerprint differs)"; });
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
    return rejected("size", [&] {
      return "size field " + std::to_string(chunk) + " but " + std::to_string(size - kPacketPrefix) + " bytes follow";
    });
  }
  if (pkt_origin == own_origin_ || relay == own_origin_) return {};  // our own packet, back over multicast
  count_gap(relay != 0 ? relay : pkt_origin, pseq);
  const auto max_encoded = static_cast<uint32_t>(slots_[0].data.size());
  if (total < static_cast<int32_t>(sizeof(MessageHeader)) || static_cast<uint32_t>(total) > limits_.max_message_bytes ||
      encoded < 0 || static_cast<uint32_t>(encoded) > max_encoded || offset < 0 ||
      static_cast<uint32_t>(offset) % kChunk != 0 || static_cast<int64_t>(offset) + chunk > encoded ||
      (static_cast<int64_t>(offset) + chunk != encoded && static_cast<uint32_t>(chunk) != kChunk) || encoding < 0 ||
      encoding > 2 || (encoding == 0 && encoded != total) ||
      (encoding == 2 && encoded <= static_cast<int32_t>(sizeof(MessageHeader))) || hops < 0 || hops > kMaxHops) {
    return rejected("fields", [&] {
      return "bad chunk fields (total " + std::to_string(total) + ", encoded " + std::to_string(encoded) + ", offset " +
             std::to_string(offset) + ", size " + std::to_string(chunk) + ", encoding " + std::to_string(encoding) +
             ", hops " + std::to_string(hops) + ", limit " + std::to_string(limits_.max_message_bytes) + " bytes)";
    });
  }
  const auto* data = reinterpret_cast<const std::byte*>(d + kPacketPrefix);
  if (offset == 0 && chunk == encoded) {  // one chunk: the common case
    return {Plan::kSingle, 0, nullptr, 0, static_cast<uint32_t>(chunk)};
  }
  for (const auto& k : skipped_) {
    if (k.first == pkt_origin && k.second == mseq && pkt_origin != 0) return {};
  }
  Slot* slot = nullptr;
  for (auto& s : slots_) {
    if (s.used && s.origin == pkt_origin && s.message_seq == mseq) slot = &s;
  }
  if (offset == 0 && encoding != 1 && !sink_.wants(data, static_cast<std::size_t>(chunk))) {
    bump(stats.not_for_us);
    skipped_[next_skipped_] = {pkt_origin, mseq};
    next_skipped_ = (next_skipped_ + 1) % skipped_.size();
    if (slot != nullptr) slot->used = false;  // chunks that came before the first
    return {};
  }
  if (slot == nullptr) {
    for (auto& s : slots_) {
      if (!s.used) {
        slot = &s;
        break;
      }
    }
    if (slot == nullptr) {  // all busy: the oldest gives way
      slot = &slots_[0];
      for (auto& s : slots_) {
        if (s.started_ns < slot->started_ns) slot = &s;
      }
      report_lost(*slot, "displaced by newer messages");
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
    log_.reject("chunk", [&] { return std::string("a chunk disagrees with its message's first chunk"); });
    return {};
  }
  const uint32_t index = static_cast<uint32_t>(offset) / kChunk;
  if (index >= slot->have.size()) {  // cannot happen after the checks above; belt and braces
    log_.reject("chunk", [&] { return "chunk index " + std::to_string(index) + " out of range"; });
    return {};
  }
  if (slot->have[index] != 0) return {};  // duplicate
  slot->have[index] = 1;
  ++slot->received;
  return {Plan::kSlot, static_cast<std::size_t>(slot - slots_.data()), slot->data.data() + offset,
          static_cast<uint32_t>(offset), static_cast<uint32_t>(chunk)};
}

ChunkReassembler::Plan ChunkReassembler::rejected(const std::string& kind, const std::function<std::string()>& why) {
  log_.reject(kind, why);
  return {};
}

// A chunk's bytes are in its slot: hands the message on when it is complete.
void ChunkReassembler::finish(const Plan& p) {
  Slot& slot = slots_[p.slot];
  if (slot.received != slot.chunks) return;
  slot.used = false;
  take_stream(slot.data.data(), true, slot.encoded, slot.total, slot.encoding, slot.origin, slot.message_seq,
              slot.hops);
}

void ChunkReassembler::unplan(const Plan& p) {
  Slot& slot = slots_[p.slot];
  slot.have[p.offset / kChunk] = 0;
  --slot.received;
}

void ChunkReassembler::take_single(const uint8_t* d, std::size_t size) {
  take_stream(reinterpret_cast<const std::byte*>(d + kPacketPrefix), false, static_cast<uint32_t>(size - kPacketPrefix),
              static_cast<uint32_t>(get_i32(d + kOffTotal)), static_cast<int8_t>(d[kOffEncoding]),
              get_i64(d + kOffOrigin), get_i32(d + kOffMessageSeq), static_cast<int8_t>(d[kOffHops]));
}

// A whole encoded message: decode it (into message_, or in place when `stream` is a
// reassembly buffer: a 4 MiB message is not copied once more), then hand it on.
void ChunkReassembler::take_stream(const std::byte* stream, bool own_buffer, uint32_t encoded, uint32_t total,
                                   int8_t encoding, int64_t origin, int32_t message_seq, int8_t hops) {
  if (encoding == 1) {
    const unsigned long long size = ZSTD_getFrameContentSize(stream, encoded);
    if (size != total) {
      return log_.reject("zstd",
                         [&] { return std::string("compressed message whose frame size differs from its total"); });
    }
    const std::size_t got = ZSTD_decompressDCtx(dctx_, message_.data(), total, stream, encoded);
    if (ZSTD_isError(got) != 0 || got != total) {
      return log_.reject("zstd", [&] {
        return std::string("compressed message does not decompress: ") +
               (ZSTD_isError(got) != 0 ? ZSTD_getErrorName(got) : "wrong size");
      });
    }
  } else if (encoding == 2) {
    // The header as it is, then the body's frame (encoded > 16: checked on receipt).
    constexpr std::size_t kHead = sizeof(MessageHeader);
    if (!sink_.wants(stream, encoded)) {  // a one-chunk message for another host: not decompressed
      bump(log_.stats().not_for_us);
      return;
    }
    const std::size_t body = total - kHead;
    const unsigned long long size = ZSTD_getFrameContentSize(stream + kHead, encoded - kHead);
    if (total < kHead || size != body) {
      return log_.reject("zstd",
                         [&] { return std::string("compressed body whose frame size differs from its total"); });
    }
    std::memcpy(message_.data(), stream, kHead);
    const std::size_t got = ZSTD_decompressDCtx(dctx_, message_.data() + kHead, body, stream + kHead, encoded - kHead);
    if (ZSTD_isError(got) != 0 || got != body) {
      return log_.reject("zstd", [&] {
        return std::string("compressed body does not decompress: ") +
               (ZSTD_isError(got) != 0 ? ZSTD_getErrorName(got) : "wrong size");
      });
    }
  } else if (own_buffer) {
    return sink_.take_message(const_cast<std::byte*>(stream), total, origin, message_seq, hops);
  } else {
    std::memcpy(message_.data(), stream, total);
  }
  sink_.take_message(message_.data(), total, origin, message_seq, hops);
}

}  // namespace rack::tims
