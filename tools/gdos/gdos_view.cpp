#include "gdos_view.h"

#include <sys/stat.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>

#include "rack/client/session.h"
#include "rack/core/payload_json.h"
#include "rack/tims/address.h"

namespace rack::gdos_view {

namespace {

// The address with its class named as the class describes itself; TiMS' spelling
// (Class0x91(2/0) for a class it does not know) when `class_name` is empty.
std::string address_text(uint32_t raw, const std::string& class_name) {
  return client::address_text(tims::Address(raw), class_name);
}

gdos::Level level_of(uint8_t l) {
  return l <= static_cast<uint8_t>(gdos::Level::kDetail) ? static_cast<gdos::Level>(l) : gdos::Level::kError;
}

std::string time_text(int64_t ns, char date_sep, bool zulu) {
  const time_t secs = static_cast<time_t>(ns / 1'000'000'000);
  tm utc{};
  gmtime_r(&secs, &utc);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02d%c%02d:%02d:%02d.%06lld%s", utc.tm_year + 1900, utc.tm_mon + 1,
                utc.tm_mday, date_sep, utc.tm_hour, utc.tm_min, utc.tm_sec,
                static_cast<long long>((ns % 1'000'000'000) / 1000), zulu ? "Z" : "");
  return buf;
}

}  // namespace

bool Filter::matches(const tims::GdosRecord& r, const std::string& display_name, const std::string& class_name) const {
  const gdos::Level l = level_of(r.level);
  if (l != gdos::Level::kPrint && l > max_level) return false;
  if (!hosts.empty()) {
    bool any = false;
    for (const auto& h : hosts) any = any || h == r.host;
    if (!any) return false;
  }
  if (!components.empty()) {
    const std::string addr = address_text(r.source & 0xFFFFFF00u, class_name);
    bool any = false;
    for (const auto& c : components) {
      if (c == display_name || c == r.name || c == addr) {
        any = true;
        break;
      }
      // An address given in another spelling (Class0x11(0/1), 17(0/1)).
      if (const auto parsed = tims::parse_address(c)) any = parsed->component().raw() == (r.source & 0xFFFFFF00u);
      if (any) break;
    }
    if (!any) return false;
  }
  if (!text.empty() && r.text.find(text) == std::string::npos) return false;
  return true;
}

// Text from the network shown on a terminal: C0 control characters (but tab), DEL
// and C1 controls (U+0080..U+009F, which some terminals take for CSI) are written as
// \xNN, so a record cannot move the cursor, retitle the window or change colours.
std::string printable(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    const bool c1 = c == 0xC2 && i + 1 < s.size() && static_cast<unsigned char>(s[i + 1]) >= 0x80 &&
                    static_cast<unsigned char>(s[i + 1]) <= 0x9F;
    if ((c < 0x20 && c != '\t') || c == 0x7F || c1) {
      const unsigned code = c1 ? static_cast<unsigned char>(s[++i]) : c;
      char esc[8];
      std::snprintf(esc, sizeof esc, "\\x%02x", code);
      out += esc;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

std::string text_line(const tims::GdosRecord& r, const std::string& display_name, bool colour,
                      const std::string& class_name) {
  const gdos::Level l = level_of(r.level);
  const char* on = "";
  if (colour) {
    switch (l) {
      case gdos::Level::kPrint: on = "\x1b[1m"; break;     // bold
      case gdos::Level::kError: on = "\x1b[1;31m"; break;  // bold red
      case gdos::Level::kWarning: on = "\x1b[33m"; break;  // yellow
      case gdos::Level::kInfo: on = ""; break;             // plain
      case gdos::Level::kDetail: on = "\x1b[2m"; break;    // dim
    }
  }
  const std::string who = printable(display_name.empty() ? address_text(r.source, class_name) : display_name);
  const std::string host = printable(r.host);
  char head[160];
  std::snprintf(head, sizeof head, "%s %-10s %c %-14s ", time_text(r.time_ns, ' ', false).c_str(), host.c_str(),
                gdos::letter(l), who.c_str());
  std::string line = on;
  line += head;
  if (r.dropped_before > 0 && r.text.find("dropped") == std::string::npos) {
    line += '[';
    line += std::to_string(r.dropped_before);
    line += " dropped before] ";
  }
  line += printable(r.text);
  if (colour && on[0] != '\0') line += "\x1b[0m";
  return line;
}

std::string json_line(const tims::GdosRecord& r, const std::string& display_name, const std::string& class_name) {
  auto q = [](const std::string& s) {
    std::string out = json_escape(s);  // (not "\"" + ...: GCC 12 warns falsely, -Wrestrict)
    out.insert(out.begin(), '"');
    out.push_back('"');
    return out;
  };
  return "{\"host\":" + q(r.host) + ",\"pid\":" + std::to_string(r.pid) + ",\"time_ns\":" + std::to_string(r.time_ns) +
         ",\"time\":" + q(time_text(r.time_ns, 'T', true)) + ",\"sequence\":" + std::to_string(r.sequence) +
         ",\"level\":" + q(gdos::describe(level_of(r.level))) + ",\"source\":" + q(address_text(r.source, class_name)) +
         ",\"source_raw\":" + std::to_string(r.source) + ",\"name\":" + q(display_name) +
         ",\"dropped_before\":" + std::to_string(r.dropped_before) + ",\"text\":" + q(r.text) + "}";
}

// ---- CRC-32 ----

uint32_t crc32(const void* data, std::size_t size) noexcept {
  static const std::array<uint32_t, 256> kTable = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1u) != 0 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  uint32_t c = 0xFFFFFFFFu;
  const auto* p = static_cast<const uint8_t*>(data);
  for (std::size_t i = 0; i < size; ++i) c = kTable[(c ^ p[i]) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

// ---- file format helpers (little-endian) ----

namespace {

constexpr char kMagic[8] = {'R', 'A', 'C', 'K', 'G', 'D', 'O', 'S'};
constexpr uint32_t kMaxRecordBytes = 16u << 20;  // a sanity bound on one record

template <class T>
void put(std::string& b, T v) {
  for (std::size_t i = 0; i < sizeof(T); ++i) b += static_cast<char>((static_cast<uint64_t>(v) >> (8 * i)) & 0xFFu);
}
void put_string16(std::string& b, const std::string& s) {
  const std::size_t n = s.size() < 0xFFFF ? s.size() : 0xFFFF;
  put<uint16_t>(b, static_cast<uint16_t>(n));
  b.append(s, 0, n);
}
void put_string32(std::string& b, const std::string& s) {
  put<uint32_t>(b, static_cast<uint32_t>(s.size()));
  b += s;
}

class Cursor {
 public:
  Cursor(const std::string& b, std::size_t at = 0) : b_(b), at_(at) {}
  template <class T>
  bool get(T& v) {
    if (at_ + sizeof(T) > b_.size()) return false;
    uint64_t x = 0;
    for (std::size_t i = 0; i < sizeof(T); ++i)
      x |= static_cast<uint64_t>(static_cast<uint8_t>(b_[at_ + i])) << (8 * i);
    v = static_cast<T>(x);
    at_ += sizeof(T);
    return true;
  }
  template <class Len>
  bool get_string(std::string& s) {
    Len n = 0;
    if (!get(n) || at_ + n > b_.size()) return false;
    s.assign(b_, at_, n);
    at_ += n;
    return true;
  }
  [[nodiscard]] std::size_t at() const { return at_; }

 private:
  const std::string& b_;
  std::size_t at_;
};

}  // namespace

FileError::FileError(const std::string& path, uint64_t offset, const std::string& what)
    : std::runtime_error(path + ": byte offset " + std::to_string(offset) + ": " + what), offset_(offset) {}

namespace {
// The path to record into, unless it is a FIFO: opening one for writing waits for a
// reader, and gdos --record hung there, silent.
const std::string& record_path(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && S_ISFIFO(st.st_mode)) {
    throw std::runtime_error(path + ": cannot create the record file: a FIFO, not a regular file");
  }
  return path;
}
}  // namespace

RecordWriter::RecordWriter(const std::string& path, const std::string& description)
    : path_(record_path(path)), out_(path, std::ios::binary | std::ios::trunc) {
  if (!out_) throw std::runtime_error(path + ": cannot create the record file: " + std::strerror(errno));
  std::string fields;
  put<int64_t>(fields, rt::host_time_ns());
  put_string16(fields, description);
  std::string h(kMagic, sizeof kMagic);
  put<uint16_t>(h, kFileVersion);
  put<uint16_t>(h, static_cast<uint16_t>(fields.size()));
  h += fields;
  out_.write(h.data(), static_cast<std::streamsize>(h.size()));
  out_.flush();
  if (!out_) throw std::runtime_error(path + ": cannot write the record file header");
}

void RecordWriter::write(const tims::GdosRecord& r) {
  std::string body;
  put<int64_t>(body, r.time_ns);
  put<uint64_t>(body, r.sequence);
  put<uint32_t>(body, r.source);
  put<uint8_t>(body, r.level);
  put<uint32_t>(body, r.dropped_before);
  put<int32_t>(body, r.pid);
  put_string16(body, r.host);
  put_string16(body, r.name);
  put_string32(body, r.text);
  std::string rec;
  put<uint32_t>(rec, static_cast<uint32_t>(body.size()));
  put<uint32_t>(rec, crc32(body.data(), body.size()));
  rec += body;
  out_.write(rec.data(), static_cast<std::streamsize>(rec.size()));
  if (!out_) throw std::runtime_error(path_ + ": write failed (disk full?)");
  ++records_;
}

void RecordWriter::flush() { out_.flush(); }

RecordReader::RecordReader(const std::string& path) : path_(path) {
  std::string error;
  if (!in_.open(path, UINT64_MAX, "gdos record file", error)) {
    // error starts with the path: the FileError adds it again with the offset.
    throw FileError(path, 0, error.substr(std::min(error.size(), path.size() + 2)));
  }
  char head[12];
  const auto got = static_cast<std::size_t>(read(head, sizeof head));
  if (got < sizeof kMagic || std::memcmp(head, kMagic, sizeof kMagic) != 0) {
    throw FileError(path, 0, "not a gdos record file (it does not start with RACKGDOS)");
  }
  if (got < sizeof head) throw FileError(path, got, "truncated header");
  const std::string hs(head, sizeof head);
  Cursor c(hs, 8);
  uint16_t version = 0, n = 0;
  (void)c.get(version);
  (void)c.get(n);
  if (version != kFileVersion) {
    throw FileError(path, 8,
                    "file format version " + std::to_string(version) + " (this gdos reads version " +
                        std::to_string(kFileVersion) + ")");
  }
  std::string fields(n, '\0');
  const auto fields_got = static_cast<std::size_t>(read(fields.data(), n));
  if (fields_got != n) {
    throw FileError(path, 12 + fields_got,
                    "truncated header (" + std::to_string(n) + " bytes of header fields announced)");
  }
  Cursor f(fields);
  if (!f.get(created_ns_) || !f.get_string<uint16_t>(description_)) {
    throw FileError(path, 12, "header fields are malformed");
  }
  offset_ = 12 + n;
}

bool RecordReader::next(tims::GdosRecord& r) {
  char pre[8];
  const auto got = static_cast<std::size_t>(read(pre, sizeof pre));
  if (got == 0) return false;
  if (got < sizeof pre) throw FileError(path_, offset_, "truncated record (the file ends inside a record's length)");
  const std::string ps(pre, sizeof pre);
  Cursor c(ps);
  uint32_t length = 0, crc = 0;
  (void)c.get(length);
  (void)c.get(crc);
  if (length > kMaxRecordBytes) {
    throw FileError(path_, offset_, "record length " + std::to_string(length) + " is implausible (corrupt file)");
  }
  // Checked against the file's size now (it may still be recorded) before the body is
  // allocated; the read below decides in the end.
  struct stat st {};
  if (::fstat(in_.fd(), &st) == 0 && st.st_size >= 0) {
    const uint64_t size = static_cast<uint64_t>(st.st_size);
    const uint64_t present = size > in_.offset() ? size - in_.offset() : 0;
    if (length > present) {
      throw FileError(path_, offset_,
                      "truncated record (" + std::to_string(length) + " bytes announced, " + std::to_string(present) +
                          " present)");
    }
  }
  std::string body(length, '\0');
  const auto body_got = static_cast<std::size_t>(read(body.data(), length));
  if (body_got != length) {
    throw FileError(path_, offset_,
                    "truncated record (" + std::to_string(length) + " bytes announced, " + std::to_string(body_got) +
                        " present)");
  }
  if (crc32(body.data(), body.size()) != crc) throw FileError(path_, offset_, "record fails its CRC (corrupt file)");
  Cursor b(body);
  r = tims::GdosRecord{};
  if (!b.get(r.time_ns) || !b.get(r.sequence) || !b.get(r.source) || !b.get(r.level) || !b.get(r.dropped_before) ||
      !b.get(r.pid) || !b.get_string<uint16_t>(r.host) || !b.get_string<uint16_t>(r.name) ||
      !b.get_string<uint32_t>(r.text) || b.at() != body.size()) {
    throw FileError(path_, offset_, "record fields do not fill its length of " + std::to_string(length) + " bytes");
  }
  offset_ += sizeof pre + length;
  return true;
}

long RecordReader::read(char* buffer, std::size_t n) {
  std::string error;
  const long got = in_.read(buffer, n, error);
  if (got < 0) throw FileError(path_, in_.offset(), error.substr(std::min(error.size(), path_.size() + 2)));
  return got;
}

}  // namespace rack::gdos_view
