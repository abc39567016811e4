#include "common/chassis_base.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "rack/core/wire.h"
#include "rack/rt/clock.h"
#include "rack/tims/address.h"
#include "rack/tims/byte_order.h"

namespace rack::components {

void ChassisBase::reset_pilot() noexcept {
  active_pilot_.store(0, std::memory_order_relaxed);
  last_move_ns_.store(rt::monotonic_ns(), std::memory_order_relaxed);
}

CommandResult ChassisBase::command(const tims::MessageHeader& request, std::span<const std::byte> body) {
  const bool native = tims::body_is_native(request);
  switch (request.type) {
    case interfaces::kChassisMove: {
      interfaces::ChassisMove m;
      if (!wire::read_payload(body, native, m)) {
        reject_malformed(request, "MOVE: body must be a ChassisMove (vx, vy, omega: 3 doubles)");
        return CommandResult::kHandled;
      }
      if (!std::isfinite(m.vx) || !std::isfinite(m.vy) || !std::isfinite(m.omega)) {
        reject_malformed(request, "MOVE: velocities must be finite");
        return CommandResult::kHandled;
      }
      const uint32_t active = active_pilot();
      if (active == 0) {
        reply_error(request, "MOVE refused: no active pilot (SET_ACTIVE_PILOT first)");
        return CommandResult::kHandled;
      }
      if (request.source().component().raw() != active) {
        reply_error(request, "MOVE refused: the sender is not the active pilot");
        return CommandResult::kHandled;
      }
      if (state() != ComponentState::kEnabled) {
        reply_error(request, "MOVE refused: the chassis is not ENABLED");
        return CommandResult::kHandled;
      }
      const interfaces::ChassisParams limits = chassis_params();
      const double vy = vy_max();
      command_velocity(Velocity{std::clamp(m.vx, -limits.vx_max, limits.vx_max), std::clamp(m.vy, -vy, vy),
                                std::clamp(m.omega, -limits.omega_max, limits.omega_max)});
      last_move_ns_.store(rt::monotonic_ns(), std::memory_order_relaxed);
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    }
    case interfaces::kChassisSetActivePilot: {
      // Decoded by hand: a 4-byte body trips GCC 12's -Warray-bounds in swap_fields.
      if (body.size() != sizeof(interfaces::ChassisSetActivePilot)) {
        reject_malformed(request, "SET_ACTIVE_PILOT: body must be one 32-bit address");
        return CommandResult::kHandled;
      }
      uint32_t raw = 0;
      std::memcpy(&raw, body.data(), sizeof raw);
      if (!native) raw = tims::bswap(raw);
      // Any mailbox of the pilot names it: the component part is what MOVE is checked against.
      const uint32_t pilot = tims::Address(raw).component().raw();
      if (pilot != active_pilot()) {
        command_velocity(Velocity{});  // a new driver starts from standstill
        active_pilot_.store(pilot, std::memory_order_relaxed);
      }
      reply(request, tims::msg::kOk);
      return CommandResult::kHandled;
    }
    case interfaces::kChassisGetParams: {
      if (!body.empty()) {
        reject_malformed(request, "GET_PARAMS takes no body");
        return CommandResult::kHandled;
      }
      reply_with(request, interfaces::kChassisParamsReply, chassis_params());
      return CommandResult::kHandled;
    }
    default: return CommandResult::kUnknown;
  }
}

}  // namespace rack::components
