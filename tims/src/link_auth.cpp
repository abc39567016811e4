#include "rack/tims/link_auth.h"

#include "rack/rt/input_file.h"
#include "rack/rt/output_file.h"

#include <fcntl.h>
#include <sodium.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace rack::tims {

namespace {

constexpr uint8_t kMagic[4] = {'R', 'K', 'A', '1'};
constexpr std::size_t kMacBytes = 16;
constexpr std::size_t kSignedTrailer = kAuthTrailerBytes - kMacBytes;  // bytes 0..31 are MAC'd
constexpr std::size_t kHexLen = kLinkKeyBytes * 2;
constexpr uint64_t kMaxKeyFileBytes = 64u << 10;  // two keys and comments fit many times over

void init_sodium() {
  // sodium_init() is idempotent and thread-safe; < 0 only when no entropy source.
  if (sodium_init() < 0) throw std::runtime_error("libsodium could not be initialised");
}

void put_be64(uint8_t* p, uint64_t v) noexcept {
  for (int i = 7; i >= 0; --i) {
    p[i] = static_cast<uint8_t>(v);
    v >>= 8;
  }
}
uint64_t get_be64(const uint8_t* p) noexcept {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}

void mac(const LinkKey& key, std::string_view channel, const uint8_t* payload, std::size_t size,
         const uint8_t* trailer_head, uint8_t* out16) noexcept {
  crypto_generichash_state st;
  crypto_generichash_init(&st, key.bytes.data(), key.bytes.size(), kMacBytes);
  const uint8_t nul = 0;
  crypto_generichash_update(&st, reinterpret_cast<const unsigned char*>(channel.data()), channel.size());
  crypto_generichash_update(&st, &nul, 1);
  crypto_generichash_update(&st, payload, size);
  crypto_generichash_update(&st, trailer_head, kSignedTrailer);
  crypto_generichash_final(&st, out16, kMacBytes);
}

std::string mode_text(mode_t m) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04o", static_cast<unsigned>(m & 07777));
  return buf;
}

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

}  // namespace

LinkKey make_link_key(const uint8_t* bytes32) {
  init_sodium();
  LinkKey k;
  std::memcpy(k.bytes.data(), bytes32, kLinkKeyBytes);
  uint8_t h[16];
  // An unkeyed hash of the key with a label: says which key signed, reveals nothing.
  static constexpr char kLabel[] = "rack-rt link key id";
  crypto_generichash_state st;
  crypto_generichash_init(&st, nullptr, 0, sizeof h);
  crypto_generichash_update(&st, reinterpret_cast<const unsigned char*>(kLabel), sizeof kLabel - 1);
  crypto_generichash_update(&st, bytes32, kLinkKeyBytes);
  crypto_generichash_final(&st, h, sizeof h);
  k.id = (uint32_t{h[0]} << 24) | (uint32_t{h[1]} << 16) | (uint32_t{h[2]} << 8) | h[3];
  return k;
}

KeyFile load_key_file(const std::string& path) {
  KeyFile out;
  const auto refuse = [&](const std::string& why) {
    out.keys.clear();
    out.error = "key file " + path + ": " + why;
    return out;
  };
  // O_NOFOLLOW is not used: a symlink to a well-protected file is fine; the checks
  // are on the file itself (fstat of what was opened). A FIFO or device is refused
  // without waiting on it (rack/rt/input_file.h).
  rt::InputFile file;
  std::string error;
  if (!file.open(path, kMaxKeyFileBytes, "key file", error)) {
    out.keys.clear();
    out.error = error;
    // The first run of a keyed host file (configs/access_control.yaml): say how to make one.
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0 && errno == ENOENT) {
      out.error += " (make one with: rackctl keygen " + path + "; the same file on every host of the network)";
    }
    return out;
  }
  if ((file.mode() & 077) != 0) {
    return refuse("has mode " + mode_text(file.mode()) +
                  ": group or others may access it, so the key is not secret; refused (chmod 600 " + path + ")");
  }
  std::string text;
  if (!file.read_all(text, error)) {
    out.keys.clear();
    out.error = error;
    return out;
  }
  file.close();
  std::istringstream in(text);
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const auto last = line.find_last_not_of(" \t\r");
    const std::string hex = line.substr(first, last - first + 1);
    const std::string where = "line " + std::to_string(number) + ": ";
    if (hex.size() != kHexLen) {
      return refuse(where + "a key is " + std::to_string(kHexLen) + " hex digits (32 bytes), got " +
                    std::to_string(hex.size()) + " characters (make one with: rackctl keygen FILE)");
    }
    uint8_t bytes[kLinkKeyBytes];
    for (std::size_t i = 0; i < kLinkKeyBytes; ++i) {
      const int hi = hex_value(hex[2 * i]);
      const int lo = hex_value(hex[2 * i + 1]);
      if (hi < 0 || lo < 0) return refuse(where + "not a hex digit at column " + std::to_string(first + 2 * i + 1));
      bytes[i] = static_cast<uint8_t>(hi * 16 + lo);
    }
    if (out.keys.size() == 2)
      return refuse(where + "more than two keys (the signing key and one more during a rotation)");
    out.keys.push_back(make_link_key(bytes));
    sodium_memzero(bytes, sizeof bytes);
  }
  sodium_memzero(text.data(), text.size());
  if (out.keys.empty()) return refuse("holds no key (make one with: rackctl keygen FILE)");
  return out;
}

std::string generate_key_file(const std::string& path) {
  init_sodium();
  // Written beside the target and linked into place when whole (rack/rt/output_file.h):
  // a write that fails (disk full) leaves no partial key file that the next keygen would
  // refuse to replace and a host would refuse to load; a FIFO is refused, not waited on.
  rt::OutputFile out;
  std::string error;
  if (!out.open(path, "key file", rt::OutputMode::kNewPrivate, error)) return error;
  uint8_t key[kLinkKeyBytes];
  randombytes_buf(key, sizeof key);
  char hex[kHexLen + 1];
  sodium_bin2hex(hex, sizeof hex, key, sizeof key);
  sodium_memzero(key, sizeof key);
  std::string text = "# RACK-RT TiMS link key (the first key signs; a second line is accepted too)\n" +
                     std::string(hex) + "\n";
  sodium_memzero(hex, sizeof hex);
  const bool ok = out.write(text, error) && out.commit(error);
  sodium_memzero(text.data(), text.size());
  return ok ? std::string() : error;
}

KeyRing::KeyRing(std::string path) : path_(std::move(path)) {
  init_sodium();
  KeyFile f = load_key_file(path_);
  if (!f.error.empty()) throw std::runtime_error(f.error);
  keys_ = std::move(f.keys);
  struct stat st {};
  if (stat(path_.c_str(), &st) == 0) {
    dev_ = st.st_dev;
    ino_ = st.st_ino;
    size_ = st.st_size;
    mtime_ns_ = st.st_mtim.tv_sec * 1'000'000'000LL + st.st_mtim.tv_nsec;
  }
}

std::string KeyRing::check_reload() {
  struct stat st {};
  if (stat(path_.c_str(), &st) != 0) {
    // Gone for a moment (an editor replacing it): keep the keys, try again later.
    return {};
  }
  const int64_t mtime = st.st_mtim.tv_sec * 1'000'000'000LL + st.st_mtim.tv_nsec;
  if (st.st_dev == dev_ && st.st_ino == ino_ && st.st_size == size_ && mtime == mtime_ns_) return {};
  dev_ = st.st_dev;
  ino_ = st.st_ino;
  size_ = st.st_size;
  mtime_ns_ = mtime;
  KeyFile f = load_key_file(path_);
  if (!f.error.empty()) return f.error + "; keeping the keys loaded before";
  const std::size_t n = f.keys.size();
  {
    std::lock_guard lock(mutex_);
    keys_ = std::move(f.keys);
  }
  generation_.fetch_add(1, std::memory_order_release);  // snapshots re-copy after this
  return "key file " + path_ + " reloaded: " + std::to_string(n) + " key(s), the first signs";
}

void KeyRing::refresh(Snapshot& s) const {
  const uint64_t g = generation_.load(std::memory_order_acquire);
  if (g == s.generation) return;
  std::lock_guard lock(mutex_);
  s.count = std::min<std::size_t>(keys_.size(), s.keys.size());
  for (std::size_t i = 0; i < s.count; ++i) s.keys[i] = keys_[i];
  s.generation = g;
}

void LinkSigner::sign(std::string_view channel, const uint8_t* payload, std::size_t size, uint8_t* trailer,
                      int64_t now_ns) {
  ring_.refresh(snap_);
  const LinkKey& key = snap_.keys[0];
  std::memcpy(trailer, kMagic, 4);
  trailer[4] = static_cast<uint8_t>(key.id >> 24);
  trailer[5] = static_cast<uint8_t>(key.id >> 16);
  trailer[6] = static_cast<uint8_t>(key.id >> 8);
  trailer[7] = static_cast<uint8_t>(key.id);
  put_be64(trailer + 8, static_cast<uint64_t>(sender_));
  put_be64(trailer + 16, ++seq_);
  put_be64(trailer + 24, static_cast<uint64_t>(now_ns));
  mac(key, channel, payload, size, trailer, trailer + kSignedTrailer);
}

const char* describe(AuthResult r) noexcept {
  switch (r) {
    case AuthResult::kOk: return "ok";
    case AuthResult::kUnsigned: return "not signed (a host without the key?)";
    case AuthResult::kUnknownKey: return "signed with a key this host does not have";
    case AuthResult::kBadMac: return "MAC does not match (tampered, or a different key)";
    case AuthResult::kOutsideWindow:
      return "time outside the replay window (an old capture, or clocks not synchronised)";
    case AuthResult::kReplayed: return "sequence number already seen (replayed)";
    case AuthResult::kTableFull: return "too many senders to track (sender table full)";
  }
  return "unknown";
}

bool looks_signed(const uint8_t* data, std::size_t size) noexcept {
  return size >= kAuthTrailerBytes && std::memcmp(data + size - kAuthTrailerBytes, kMagic, 4) == 0;
}

AuthResult LinkVerifier::verify(std::string_view channel, const uint8_t* data, std::size_t size, int64_t now_ns,
                                int64_t mono_ns) {
  last_sender_ = 0;
  if (!looks_signed(data, size)) return AuthResult::kUnsigned;
  const std::size_t payload = size - kAuthTrailerBytes;
  const uint8_t* t = data + payload;
  const uint32_t id = (uint32_t{t[4]} << 24) | (uint32_t{t[5]} << 16) | (uint32_t{t[6]} << 8) | t[7];
  ring_.refresh(snap_);
  const LinkKey* key = nullptr;
  for (std::size_t i = 0; i < snap_.count; ++i) {
    if (snap_.keys[i].id == id) key = &snap_.keys[i];
  }
  if (key == nullptr) return AuthResult::kUnknownKey;
  uint8_t expected[kMacBytes];
  mac(*key, channel, data, payload, t, expected);
  if (crypto_verify_16(expected, t + kSignedTrailer) != 0) return AuthResult::kBadMac;
  // Authentic from here on: the fields can be trusted.
  const auto sender = static_cast<int64_t>(get_be64(t + 8));
  const uint64_t seq = get_be64(t + 16);
  const auto time = static_cast<int64_t>(get_be64(t + 24));
  last_sender_ = sender;
  if (time < now_ns - window_ns_ || time > now_ns + window_ns_) return AuthResult::kOutsideWindow;
  const auto start = static_cast<std::size_t>(static_cast<uint64_t>(sender) * 0x9E3779B97F4A7C15ULL >> 56);
  Sender* entry = nullptr;
  Sender* free_entry = nullptr;
  for (std::size_t p = 0; p < kProbe; ++p) {
    Sender& s = senders_[(start + p) % kSenders];
    if (s.id == sender) {
      entry = &s;
      break;
    }
    // A sender silent for two windows: its captured packets are outside the window.
    if (free_entry == nullptr && (s.id == 0 || mono_ns - s.last_ns > 2 * window_ns_)) free_entry = &s;
  }
  if (entry == nullptr) {
    if (free_entry == nullptr) return AuthResult::kTableFull;
    *free_entry = Sender{sender, seq, 1, mono_ns};
    return AuthResult::kOk;
  }
  if (seq > entry->highest) {
    const uint64_t shift = seq - entry->highest;
    entry->seen = shift >= 64 ? 1 : (entry->seen << shift) | 1;
    entry->highest = seq;
  } else {
    const uint64_t back = entry->highest - seq;
    if (back >= 64 || (entry->seen & (uint64_t{1} << back)) != 0) return AuthResult::kReplayed;
    entry->seen |= uint64_t{1} << back;
  }
  entry->last_ns = mono_ns;
  return AuthResult::kOk;
}

}  // namespace rack::tims
