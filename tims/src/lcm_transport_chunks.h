// A TiMS message on the wire (internal to tims): ChunkPublisher cuts a message into
// tims_packet chunks below LCM's fragmentation size (lcm_transport_packet.h), its body
// compressed (zstd) where the network asks for it; ChunkReassembler checks every
// packet's fields and puts the chunks together again in preallocated slots, within its
// limits (message size, messages at once, time to complete), and hands whole messages
// on. Both work on plain byte buffers: the publisher hands packets to a PacketOut, the
// reassembler takes them from any caller (the network's receive thread, a test, a
// fuzz harness) and hands messages to a MessageSink.
//
// Real-time contract: nothing here is RT-safe (the transport's non-RT threads; the
// buffers are allocated by the constructors, not per message). Thread-safety: one
// ChunkPublisher per network, used under its publish lock; one ChunkReassembler per
// network, used by its receive thread only.
#pragma once

#include <zstd.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

#include "lcm_transport_stats.h"

namespace rack::tims {

// Where a publisher's packets go: `buf` holds `len` bytes (prefix and chunk) and room
// for `trailer_bytes` more (the publisher's constructor says how many: a keyed network
// appends its MAC there). Returns 0 when published (LCM's publish()).
class PacketOut {
 public:
  virtual ~PacketOut() = default;
  virtual int send_packet(uint8_t* buf, std::size_t len) = 0;
};

class ChunkPublisher {
 public:
  // `trailer_bytes`: room kept after every packet (the authentication trailer; 0 on an
  // unkeyed network). Compresses when `config.compression` asks for it.
  ChunkPublisher(const NetworkConfig& config, uint32_t max_message_bytes, std::size_t trailer_bytes, NetworkLog& log);
  ~ChunkPublisher();
  ChunkPublisher(const ChunkPublisher&) = delete;
  ChunkPublisher& operator=(const ChunkPublisher&) = delete;

  // Publishes one TiMS message (host byte order header at the start) as chunks.
  // `writable`: the caller owns `msg` and lets it be used as scratch (restored before
  // return), so that chunks after the first go out in place (the 50-byte prefix
  // written over the tail of the chunk before, which has been sent) instead of being
  // copied into the packet buffer first. False when a packet could not be published
  // (counted: publish_errors, and said).
  bool publish(const std::byte* msg, uint32_t len, int64_t origin, int64_t relay, int8_t hops, int32_t seq,
               bool writable, PacketOut& out);

 private:
  NetworkLog& log_;
  uint32_t compress_min_bytes_;
  std::size_t trailer_bytes_;
  uint32_t packet_seq_ = 0;
  std::vector<uint8_t> packet_;  // prefix + one chunk + trailer
  std::vector<std::byte> compressed_;
  ZSTD_CCtx* cctx_ = nullptr;  // null: the network does not compress
};

// What a reassembler asks its receiver, and hands it.
class MessageSink {
 public:
  virtual ~MessageSink() = default;
  // A message's first chunk begins with its TiMS header (`head`, any byte order, at
  // least `size` bytes): whether the message is worth reassembling here (for a local
  // mailbox; anything for a router; a request this host may answer).
  virtual bool wants(const std::byte* head, std::size_t size) = 0;
  // A whole message, decompressed, `len` bytes at `msg` (writable: the receiver puts
  // its header into host byte order). Valid until the call returns.
  virtual void take_message(std::byte* msg, uint32_t len, int64_t origin, int32_t message_seq, int8_t hops) = 0;
};

struct ChunkLimits {
  uint32_t max_message_bytes = 4 * 1024 * 1024 + 4096;  // largest message accepted (total)
  uint32_t slots = 4;                                   // messages reassembled at once
  int64_t timeout_ns = 1'000'000'000;                   // an incomplete message is lost after this
};

class ChunkReassembler {
 public:
  // Where a chunk's bytes go: nowhere (dropped, counted as the checks say), a
  // single-chunk message (handled from the datagram), or reassembly slot `slot` at
  // `into` (its buffer at the chunk's offset), `size` bytes.
  struct Plan {
    enum Kind : uint8_t { kDrop, kSingle, kSlot } kind = kDrop;
    std::size_t slot = 0;
    std::byte* into = nullptr;
    uint32_t offset = 0;
    uint32_t size = 0;
  };

  // `own_origin`: this transport's origin (its own packets, echoed by multicast, are
  // dropped). Allocates every slot for the largest message (compressed streams may be
  // a little larger: zstd's bound).
  ChunkReassembler(int64_t own_origin, const ChunkLimits& limits, NetworkLog& log, MessageSink& sink);
  ~ChunkReassembler();
  ChunkReassembler(const ChunkReassembler&) = delete;
  ChunkReassembler& operator=(const ChunkReassembler&) = delete;

  // A whole tims_packet of `size` bytes (one datagram's payload on `channel`).
  void on_packet(const uint8_t* d, std::size_t size, std::string_view channel);

  // The parts of on_packet for a reader that looks before it reads (the udpm socket):
  // plan() validates a packet of `size` bytes of which the prefix and, for a first
  // chunk, the message header are at `d` (the rest may still be in the socket), and
  // says where its bytes go. A chunk planned into a slot counts as received there: the
  // caller copies its bytes to plan.into and calls finish(), or unplan() when the read
  // failed after all (the slot waits for it again, as for a lost datagram).
  Plan plan(const uint8_t* d, std::size_t size, std::string_view channel);
  void finish(const Plan& p);
  void unplan(const Plan& p);
  // A packet planned kSingle and then read whole (`size` bytes at `d`): its message.
  void take_single(const uint8_t* d, std::size_t size);

  // Reports (lost_messages, said) and frees every slot older than the timeout.
  void expire(int64_t now_ns);

 private:
  // A large message being received, in a preallocated buffer.
  struct Slot {
    bool used = false;
    int64_t origin = 0;
    int32_t message_seq = 0;
    uint32_t total = 0;
    uint32_t encoded = 0;
    int8_t encoding = 0;
    int8_t hops = 0;
    uint32_t chunks = 0;
    uint32_t received = 0;
    int64_t started_ns = 0;
    std::vector<std::byte> data;
    std::vector<uint8_t> have;  // one flag per chunk
  };

  Plan rejected(const std::string& kind, const std::function<std::string()>& why);
  void count_gap(int64_t publisher, uint32_t seq);
  void report_lost(Slot& s, const char* why);
  void take_stream(const std::byte* stream, bool own_buffer, uint32_t encoded, uint32_t total, int8_t encoding,
                   int64_t origin, int32_t message_seq, int8_t hops);

  int64_t own_origin_;
  ChunkLimits limits_;
  NetworkLog& log_;
  MessageSink& sink_;
  std::vector<Slot> slots_;
  // Large messages for someone else, recognised by their first chunk: their other
  // chunks are dropped at once instead of reassembled (on a shared network every
  // host hears every 4 MB scan). A small ring of (origin, message number).
  std::array<std::pair<int64_t, int32_t>, 16> skipped_{};
  std::size_t next_skipped_ = 0;
  std::vector<std::byte> message_;  // a whole message in host byte order, for delivery
  ZSTD_DCtx* dctx_ = nullptr;
  std::unordered_map<int64_t, uint32_t> last_packet_seq_;  // per publisher
};

}  // namespace rack::tims
