// MRPT rawlog reader (private: the only place of the replay component that sees MRPT;
// this header does not include it). Not RT-safe (set-up only).
#pragma once

#include <string>

#include "rack/replay/replay_log.h"

namespace rack::replay {

// Reads an MRPT rawlog (plain or gzip). Errors name the file, the entry index and
// the byte offset of an unreadable record.
[[nodiscard]] LoadLogResult load_rawlog(const std::string& path);

}  // namespace rack::replay
