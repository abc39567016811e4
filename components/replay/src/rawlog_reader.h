// MRPT rawlog reader (private: the only place of the replay component that sees MRPT;
// this header does not include it). Not RT-safe (set-up only).
#pragma once

#include <string>

#include "rack/replay/replay_log.h"

namespace rack::replay {

// Reads an MRPT rawlog (plain or gzip). Errors name the file, the entry index and
// the byte offset of an unreadable record. The file must be a regular file of at most
// kMaxLogFileBytes; gzip data may decompress to at most kMaxRawlogBytes (checked while
// inflating: a gzip bomb stops at the limit). MRPT's deserialisation runs in a forked
// child with memory and CPU limits (MRPT crashes, exits and over-allocates on corrupt
// data): its death is an error naming the record. Never throws for bad input.
[[nodiscard]] LoadLogResult load_rawlog(const std::string& path);
// The same for a file's bytes in memory (`name` for the messages), in this process:
// what the tests and the fuzz harness drive. Reads only up to the first image object
// (MRPT's JPEG decoder calls exit() on a corrupt image).
[[nodiscard]] LoadLogResult parse_rawlog(const std::string& name, const std::string& bytes);
// Inflates gzip data (RFC 1952, concatenated members too) into `out`, at most
// `max_out` bytes. false with `error` (the reason and the byte offset in `in`).
[[nodiscard]] bool gunzip_bounded(const std::string& in, uint64_t max_out, std::string& out, std::string& error);

}  // namespace rack::replay
