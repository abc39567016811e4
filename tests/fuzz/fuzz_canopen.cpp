// CANopen frames from a drive (components/devices: CanPort over a socket that carries
// struct can_frame, the SDO response parser, the SDO client transfers and the PDO and
// heartbeat decoding the CAN drivers do). The frames arrive as packets on a real
// SOCK_SEQPACKET socketpair, as from the CiA 402 simulator or a broken peer: any
// packet size, any length byte, error frames, filters.
//
// Input: byte 0 the node id (1..127), byte 1 the mode (0: drain and decode every
// frame as a driver does; 1: an SDO read; 2: the CiA 402 power-up), byte 2 the number
// of software filters (0..4, 8 bytes each, then read from the input), then packets:
// a length byte (0..32) and that many bytes, up to 64 packets. The peer then shuts
// its side, so a transfer waiting for more sees the end at once.
// Properties: receive() delivers only 16-byte frames with len <= 8 and counts every
// other packet; delivered + filtered + malformed + error frames adds up to what
// arrived.
#include <linux/can.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "fuzz_support.h"
#include "rack/devices/can_port.h"
#include "rack/devices/canopen.h"
#include "rack/devices/canopen_client.h"

namespace co = rack::devices::canopen;
using rack::devices::CanPort;
using rack::devices::IoStatus;

namespace {

constexpr int64_t kTimeoutNs = 100'000'000;  // never reached: the peer's end ends a wait

// What ServoDriveCan and ChassisCan take from a frame of their node.
void decode_as_driver(const can_frame& f, uint8_t node) {
  const canid_t id = f.can_id & CAN_SFF_MASK;
  if (id == co::kHeartbeat + node && f.len >= 1) {
    (void)f.data[0];
  } else if (id == co::kTpdo1 + node && f.len == 8) {
    (void)static_cast<int32_t>(co::get_u32(&f.data[0]));
    (void)static_cast<int32_t>(co::get_u32(&f.data[4]));
  } else if (id == co::kTpdo2 + node && f.len >= 2) {
    (void)co::get_u16(&f.data[0]);
  }
  const co::SdoResponse r = co::parse_sdo_response(f, node);
  if (r.kind != co::SdoResponse::Kind::kNone) FUZZ_CHECK(f.len == 8);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  rack::fuzz::FuzzInput in(data, size);
  const auto node = static_cast<uint8_t>(1 + in.byte() % 127);
  const uint8_t mode = in.byte() % 3;
  can_filter filters[4];
  const std::size_t filter_count = in.byte() % 5;
  for (std::size_t i = 0; i < filter_count; ++i) {
    filters[i].can_id = in.take<canid_t>();
    filters[i].can_mask = in.take<canid_t>();
  }
  int sv[2];
  FUZZ_CHECK(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv) == 0);
  CanPort port;
  port.adopt(sv[0]);
  std::string error;
  FUZZ_CHECK(port.set_filters(std::span<const can_filter>(filters, filter_count), error));
  uint64_t sent = 0;
  while (!in.empty() && sent < 64) {
    const auto packet = in.bytes(in.byte() % 33);
    if (packet.empty()) continue;  // a 0-byte packet reads as the peer's end (CanPort says so)
    FUZZ_CHECK(send(sv[1], packet.data(), packet.size(), MSG_DONTWAIT) == static_cast<ssize_t>(packet.size()));
    ++sent;
  }
  FUZZ_CHECK(shutdown(sv[1], SHUT_WR) == 0);
  if (mode == 0) {
    for (;;) {
      can_frame f{};
      const auto r = port.receive(f, kTimeoutNs);
      if (r.status != IoStatus::kOk) {
        FUZZ_CHECK(r.status == IoStatus::kClosed);  // the peer's end, never a timeout
        break;
      }
      FUZZ_CHECK(f.len <= CAN_MAX_DLEN);
      if ((f.can_id & CAN_ERR_FLAG) == 0) decode_as_driver(f, node);
    }
    const auto& c = port.counters();
    FUZZ_CHECK(c.received + c.filtered + c.malformed + c.error_frames == sent);
  } else if (mode == 1) {
    uint32_t value = 0;
    (void)co::sdo_read_wait(port, node, co::kObjStatusword, 0, value, kTimeoutNs);
  } else {
    (void)co::power_up(port, node, kTimeoutNs);
  }
  port.close();
  close(sv[1]);
  return 0;
}
