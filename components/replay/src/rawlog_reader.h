// MRPT rawlog reader (private: the only place of the replay component that sees MRPT;
// this header does not include it). Not RT-safe (set-up only).
#pragma once

#include <string>

#include "rack/replay/replay_log.h"

namespace rack::replay {

// Reads an MRPT rawlog (plain or gzip). Errors name the file, the entry index and
// the byte offset of an unreadable record. The file must be a regular file of at most
// kMaxLogFileBytes; gzip data may decompress to at most kMaxRawlogBytes (checked while
// inflating: a gzip bomb stops at the limit). Never throws for bad input.
[[nodiscard]] LoadLogResult load_rawlog(const std::string& path);
// The same for a file's bytes in memory (`name` for the messages): what a fuzz
// harness drives.
[[nodiscard]] LoadLogResult parse_rawlog(const std::string& name, const std::string& bytes);
// Inflates gzip data (RFC 1952, concatenated members too) into `out`, at most
// `max_out` bytes. false with `error` (the reason and the byte offset in `in`).
[[nodiscard]] bool gunzip_bounded(const std::string& in, uint64_t max_out, std::string& out, std::string& error);

}  // namespace rack::replay
