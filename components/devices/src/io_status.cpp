#include "rack/devices/io_status.h"

namespace rack::devices {

const char* describe(IoStatus s) noexcept {
  switch (s) {
    case IoStatus::kOk: return "ok";
    case IoStatus::kTimeout: return "timeout";
    case IoStatus::kClosed: return "device closed";
    case IoStatus::kError: return "I/O error";
  }
  return "?";
}

}  // namespace rack::devices
