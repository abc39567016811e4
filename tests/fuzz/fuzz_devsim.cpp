// libFuzzer harness for what rack-devsim's simulated devices read from the driver under
// test (components/sims: rack-devsim hokuyo, sick, cia402). A user points their own
// driver at them, so their input is any bytes: the Hokuyo's SCIP command lines
// (HokuyoScipSim::receive), the SICK's CoLa-A telegrams (SickLms1xxSim::receive), and
// CAN packets to the CiA 402 drives (Cia402DriveSim::receive, advance).
//
// Input: byte 0 picks the device (mod 3: hokuyo, sick, cia402). Hokuyo and SICK: byte 1
// sets the size of the reads (1..64 bytes), the rest is the stream. CiA 402: records of
// one op byte: below 0x40 a 16-byte struct can_frame follows (as CanPort sends it),
// 0x40..0x7f a packet of (op - 0x40) bytes (a broken sender), 0x80 and up the drives
// move (op - 0x80) ms. Properties: no crash, hang or unbounded memory; the drives'
// statusword is one of the CiA 402 power states, velocity and position finite.
//
// Seeds: tests/fuzz/corpus/devsim/ (the Hokuyo driver's start-up and an MD, the SICK
// driver's login and scan request, a CANopen master's start-up of two drives).
#include <linux/can.h>

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "fuzz_support.h"
#include "rack/devices/canopen.h"
#include "rack/sims/cia402_sim.h"
#include "rack/sims/hokuyo_scip_sim.h"
#include "rack/sims/sick_lms1xx_sim.h"

namespace co = rack::devices::canopen;

namespace {

void check_drive(const rack::sims::Cia402DriveSim::DriveState& s) {
  const auto state = static_cast<uint16_t>(s.statusword & co::kSwStateMask);
  FUZZ_CHECK((s.statusword & co::kSwFault) != 0 || (state & 0x4F) == co::kSwSwitchOnDisabled ||
             state == co::kSwReadyToSwitchOn || state == co::kSwSwitchedOn || state == co::kSwOperationEnabled);
  FUZZ_CHECK(std::isfinite(s.velocity) && std::isfinite(s.position));
}

void cia402(rack::fuzz::FuzzInput& in) {
  rack::sims::Cia402DriveSim sim(rack::sims::Cia402DriveSim::Config{.nodes = {1, 2}, .tick_ns = 1'000'000});
  int64_t now = 1'000'000'000;
  while (!in.empty()) {
    const uint8_t op = in.byte();
    if (op < 0x40) {
      const auto frame = in.bytes(sizeof(can_frame));
      if (frame.size() == sizeof(can_frame)) sim.receive(frame.data(), frame.size());
    } else if (op < 0x80) {
      const auto packet = in.bytes(op - 0x40U);
      sim.receive(packet.data(), packet.size());
    } else {
      const int64_t dt = (op - 0x80) * 1'000'000;
      now += dt;
      sim.advance(static_cast<double>(dt) * 1e-9, now);
    }
  }
  check_drive(sim.state(1));
  check_drive(sim.state(2));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rack::fuzz::FuzzInput in(data, size);
  const uint8_t device = in.byte() % 3;
  if (device == 2) {
    cia402(in);
    return 0;
  }
  const std::size_t piece = 1 + in.byte() % 64;
  if (device == 0) {
    rack::sims::HokuyoScipSim sim(rack::sims::HokuyoScipSim::Config{});
    while (!in.empty()) {
      const auto read = in.bytes(piece);
      sim.receive(reinterpret_cast<const char*>(read.data()), read.size());
    }
  } else {
    rack::sims::SickLms1xxSim sim(rack::sims::SickLms1xxSim::Config{});
    while (!in.empty()) {
      const auto read = in.bytes(piece);
      sim.receive(reinterpret_cast<const char*>(read.data()), read.size());
    }
  }
  return 0;
}
