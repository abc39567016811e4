// The gdos viewer's parts that tests use: record filters, the text and JSON line
// formats, and the record file (--record / --replay).
//
// Record file format (version 1), all integers little-endian:
//   header:  "RACKGDOS" (8 bytes), u16 version (1), u16 n = bytes of header fields
//            that follow, then n bytes: i64 created_ns (host clock), u16 length +
//            text describing the recorder (the LCM URL). Readers skip fields they
//            do not know (n may grow in later versions).
//   records: u32 length L of the body, u32 CRC-32 (IEEE) of the body, then the L
//            bytes of the body: i64 time_ns, u64 sequence, u32 source, u8 level,
//            u32 dropped_before, i32 pid, u16+host, u16+name, u32+text.
// A reader rejects a file that is not one (magic, version), and a record that is
// truncated, fails its CRC or whose fields do not fill its length exactly, naming
// the byte offset where the problem starts.
//
// Not RT code (a tool).
#pragma once

#include <cstdint>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "rack/core/gdos.h"
#include "rack/rt/input_file.h"
#include "rack/tims/gdos_lcm.h"

namespace rack::gdos_view {

struct Filter {
  gdos::Level max_level = gdos::Level::kDetail;  // show records at or below this level
  std::vector<std::string> hosts;                // empty: every host
  std::vector<std::string> components;           // names or addresses; empty: all
  std::string text;                              // substring of the text; empty: all
  // `display_name` is the name the viewer shows (record's, announced, or ""); a
  // component given as an address matches in TiMS' spelling (Class0x91(2/0), 145(2/0))
  // and, when `class_name` is the name the source's class describes itself with
  // (GET_CLASS), in that name's (Counter(2/0)).
  [[nodiscard]] bool matches(const tims::GdosRecord& r, const std::string& display_name,
                             const std::string& class_name = {}) const;
};

// "2026-11-21 23:41:02.123456 host     W name        : text" with ANSI colours by
// level when `colour` (no colours in a pipe). Ends without a newline.
// `class_name` (in text_line and json_line): the name the source's class describes
// itself with, for its address (Counter(2/0)); empty: TiMS' spelling (Class0x91(2/0)).
// `s` with control characters (C0 but tab, DEL, C1) written as \xNN: network text on a terminal.
[[nodiscard]] std::string printable(const std::string& s);
[[nodiscard]] std::string text_line(const tims::GdosRecord& r, const std::string& display_name, bool colour,
                                    const std::string& class_name = {});
// One JSON object: host, pid, time_ns, time (ISO 8601 UTC), sequence, level, source
// (address text), source_raw, name, dropped_before, text.
[[nodiscard]] std::string json_line(const tims::GdosRecord& r, const std::string& display_name,
                                    const std::string& class_name = {});

// A problem in a record file, with the byte offset where it starts.
class FileError : public std::runtime_error {
 public:
  FileError(const std::string& path, uint64_t offset, const std::string& what);
  [[nodiscard]] uint64_t offset() const noexcept { return offset_; }

 private:
  uint64_t offset_;
};

inline constexpr uint16_t kFileVersion = 1;

class RecordWriter {
 public:
  // Creates (truncates) `path` and writes the header. Throws std::runtime_error.
  RecordWriter(const std::string& path, const std::string& description);
  void write(const tims::GdosRecord& r);  // throws on a write error
  void flush();
  [[nodiscard]] uint64_t records() const noexcept { return records_; }

 private:
  std::string path_;
  std::ofstream out_;
  uint64_t records_ = 0;
};

class RecordReader {
 public:
  // Opens `path` and checks the header. Throws FileError, also when `path` is not a
  // regular file (a FIFO or device is refused without waiting on it).
  explicit RecordReader(const std::string& path);
  // The next record; false at the clean end of the file. Throws FileError.
  bool next(tims::GdosRecord& r);
  [[nodiscard]] const std::string& description() const noexcept { return description_; }
  [[nodiscard]] int64_t created_ns() const noexcept { return created_ns_; }

 private:
  // Read to its end, however long (records are streamed, one at a time).
  long read(char* buffer, std::size_t n);
  std::string path_;
  rt::InputFile in_;
  uint64_t offset_ = 0;
  std::string description_;
  int64_t created_ns_ = 0;
};

// CRC-32 (IEEE 802.3, as zlib's crc32).
[[nodiscard]] uint32_t crc32(const void* data, std::size_t size) noexcept;

}  // namespace rack::gdos_view
