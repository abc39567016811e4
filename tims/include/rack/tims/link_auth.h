// Authenticated TiMS links: a MAC on every packet of a keyed LCM network, with a
// per-sender sequence number and a time window against replay.
//
// Every payload that TiMS publishes on a keyed network (channels TIMS, TIMS_ANNOUNCE,
// TIMS_DISCOVER) carries a 48-byte trailer:
//   0  "RKA1"            magic
//   4  key id            4 bytes: which key signed (BLAKE2b of the key, cut)
//   8  sender            8 bytes: the publishing transport's origin (random per process)
//   16 sequence          8 bytes: per sender and network, +1 per packet
//   24 time              8 bytes: the sender's CLOCK_REALTIME in ns
//   32 MAC               16 bytes: keyed BLAKE2b (libsodium crypto_generichash) over
//                        the channel name, its NUL, the payload and bytes 0..31
// (integers big-endian). A receiver drops, and counts, a packet without a valid
// trailer (`auth failed`: unsigned, unknown key, wrong MAC), and a valid one whose
// time is outside the window or whose sequence number it has seen (`replayed`: a
// bitmap of the last 64 numbers per sender allows reordering). Per-sender state is a
// fixed table (kSenders); a sender silent for two windows gives its entry up (its
// old packets are outside the window by then).
//
// Keys come from a key file (never from the host file): one or two lines of 64 hex
// digits (32 bytes), '#' comments and blank lines ignored. The first key signs; both
// verify, so keys change without a restart (rotation: [old, new] on every host, then
// [new, old], then [new]). The file must be a regular file that neither group nor
// others may access (mode 0600 or stricter), or it is refused with its path and mode.
// A running transport re-reads the file when it changes (check_reload()).
//
// Real-time contract: nothing here is RT-safe in the sense of RT tasks; sign() and
// verify() do not allocate and run in the transport's non-RT threads.
// Thread-safety: KeyRing: any thread (a mutex guards the keys; each user keeps a
// snapshot refreshed by generation). LinkSigner: one thread at a time (the network's
// publish lock). LinkVerifier: one thread (the network's receive thread).
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <sys/types.h>
#include <vector>

namespace rack::tims {

inline constexpr std::size_t kLinkKeyBytes = 32;
inline constexpr std::size_t kAuthTrailerBytes = 48;
inline constexpr int64_t kDefaultReplayWindowNs = 5'000'000'000;

struct LinkKey {
  std::array<uint8_t, kLinkKeyBytes> bytes{};
  uint32_t id = 0;  // from the key (BLAKE2b, cut): says which key signed a packet
};

// Makes a key from its bytes (computes the id). Not RT-safe.
[[nodiscard]] LinkKey make_link_key(const uint8_t* bytes32);

struct KeyFile {
  std::vector<LinkKey> keys;  // one or two; the first signs
  std::string error;          // non-empty: refused ("PATH: why")
};

// Reads and checks a key file (see above). Not RT-safe.
[[nodiscard]] KeyFile load_key_file(const std::string& path);
// Writes a new key file holding one fresh random key, mode 0600; refuses to overwrite
// an existing file. "" on success, else the reason. Not RT-safe.
[[nodiscard]] std::string generate_key_file(const std::string& path);

// The keys of one network, reloaded when the file changes.
class KeyRing {
 public:
  // Loads `path`; throws std::runtime_error with the reason when refused.
  explicit KeyRing(std::string path);
  // Re-reads the file when its inode, size or modification time changed. Returns a
  // message when something happened (reloaded, or refused: the old keys stay), else "".
  std::string check_reload();

  struct Snapshot {
    uint64_t generation = 0;
    std::array<LinkKey, 2> keys{};
    std::size_t count = 0;
  };
  // Copies the keys into `s` when they changed since `s` was taken (cheap otherwise).
  void refresh(Snapshot& s) const;
  [[nodiscard]] const std::string& path() const noexcept { return path_; }

 private:
  std::string path_;
  mutable std::mutex mutex_;
  std::vector<LinkKey> keys_;
  std::atomic<uint64_t> generation_{1};  // release after keys_ change; snapshots acquire
  dev_t dev_ = 0;
  ino_t ino_ = 0;
  off_t size_ = 0;
  int64_t mtime_ns_ = 0;
};

// Appends trailers (one per network; under the network's publish lock).
class LinkSigner {
 public:
  LinkSigner(const KeyRing& ring, int64_t sender) : ring_(ring), sender_(sender) {}
  // Writes the trailer for `channel` + payload into `trailer` (48 bytes). `now_ns`:
  // CLOCK_REALTIME. Does not allocate.
  void sign(std::string_view channel, const uint8_t* payload, std::size_t size, uint8_t* trailer, int64_t now_ns);

 private:
  const KeyRing& ring_;
  KeyRing::Snapshot snap_;
  int64_t sender_;
  uint64_t seq_ = 0;
};

enum class AuthResult : uint8_t {
  kOk,
  kUnsigned,       // no trailer
  kUnknownKey,     // signed with a key this host does not have
  kBadMac,         // tampered, or signed with a different key of the same id
  kOutsideWindow,  // time too far from ours (old capture, or clocks not synchronised)
  kReplayed,       // sequence number seen before (or too old to tell)
  kTableFull,      // too many live senders to keep track of
};
[[nodiscard]] const char* describe(AuthResult r) noexcept;
[[nodiscard]] constexpr bool is_replay(AuthResult r) noexcept {
  return r == AuthResult::kOutsideWindow || r == AuthResult::kReplayed;
}

// Checks trailers (one per network; its receive thread).
class LinkVerifier {
 public:
  static constexpr std::size_t kSenders = 256;
  static constexpr std::size_t kProbe = 16;

  LinkVerifier(const KeyRing& ring, int64_t window_ns) : ring_(ring), window_ns_(window_ns) {}
  // `size` includes the trailer; on kOk the payload is the first size - 48 bytes.
  // `now_ns`: CLOCK_REALTIME; `mono_ns`: CLOCK_MONOTONIC (entry ageing). Does not
  // allocate.
  AuthResult verify(std::string_view channel, const uint8_t* data, std::size_t size, int64_t now_ns, int64_t mono_ns);
  // The sender of the last packet verify() looked at (for messages).
  [[nodiscard]] int64_t last_sender() const noexcept { return last_sender_; }

 private:
  struct Sender {
    int64_t id = 0;  // 0: free
    uint64_t highest = 0;
    uint64_t seen = 0;  // bit i: highest - i was seen
    int64_t last_ns = 0;
  };
  const KeyRing& ring_;
  KeyRing::Snapshot snap_;
  int64_t window_ns_;
  std::array<Sender, kSenders> senders_{};
  int64_t last_sender_ = 0;
};

// Whether a payload ends in something that looks like a trailer (for a clear message
// on a network without a key). Does not allocate.
[[nodiscard]] bool looks_signed(const uint8_t* data, std::size_t size) noexcept;

}  // namespace rack::tims
