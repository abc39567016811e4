#include "rack/devices/canopen_client.h"

#include "rack/rt/clock.h"

namespace rack::devices::canopen {

const char* describe(SdoResult r) noexcept {
  switch (r) {
    case SdoResult::kOk: return "ok";
    case SdoResult::kAbort: return "SDO abort";
    case SdoResult::kTimeout: return "SDO timeout";
    case SdoResult::kBusError: return "bus error";
  }
  return "?";
}

namespace {
SdoResult transfer(CanPort& port, const can_frame& request, uint8_t node, uint16_t index, uint8_t sub,
                   SdoResponse::Kind expect, uint32_t* value, int64_t timeout_ns) noexcept {
  if (port.send(request).status != IoStatus::kOk) return SdoResult::kBusError;
  const int64_t deadline = rt::monotonic_ns() + timeout_ns;
  for (;;) {
    const int64_t left = deadline - rt::monotonic_ns();
    if (left <= 0) return SdoResult::kTimeout;
    can_frame f{};
    const IoResult r = port.receive(f, left);
    if (r.status == IoStatus::kTimeout) return SdoResult::kTimeout;
    if (r.status != IoStatus::kOk) return SdoResult::kBusError;
    const SdoResponse s = parse_sdo_response(f, node);
    if (s.kind == SdoResponse::Kind::kNone || s.index != index || s.sub != sub) continue;  // another frame
    if (s.kind == SdoResponse::Kind::kAbort) return SdoResult::kAbort;
    if (s.kind != expect) return SdoResult::kAbort;
    if (value != nullptr) *value = s.value;
    return SdoResult::kOk;
  }
}
}  // namespace

SdoResult sdo_write_wait(CanPort& port, uint8_t node, uint16_t index, uint8_t sub, uint32_t value, uint8_t size,
                         int64_t timeout_ns) noexcept {
  return transfer(port, sdo_write(node, index, sub, value, size), node, index, sub, SdoResponse::Kind::kWriteOk,
                  nullptr, timeout_ns);
}

SdoResult sdo_read_wait(CanPort& port, uint8_t node, uint16_t index, uint8_t sub, uint32_t& value,
                        int64_t timeout_ns) noexcept {
  return transfer(port, sdo_read(node, index, sub), node, index, sub, SdoResponse::Kind::kReadOk, &value, timeout_ns);
}

bool power_up(CanPort& port, uint8_t node, int64_t timeout_ns) noexcept {
  uint32_t sw = 0;
  return sdo_write_wait(port, node, kObjControlword, 0, kCwShutdown, 2, timeout_ns) == SdoResult::kOk &&
         sdo_write_wait(port, node, kObjControlword, 0, kCwSwitchOn, 2, timeout_ns) == SdoResult::kOk &&
         sdo_write_wait(port, node, kObjControlword, 0, kCwEnableOperation, 2, timeout_ns) == SdoResult::kOk &&
         sdo_read_wait(port, node, kObjStatusword, 0, sw, timeout_ns) == SdoResult::kOk &&
         (sw & kSwStateMask) == kSwOperationEnabled;
}

}  // namespace rack::devices::canopen
