// libFuzzer harness: the receive path of the TiMS/LCM transport for one UDP datagram
// (LcmTransport::handle_datagram: LCM's framing, authentication check, tims_packet
// chunks and their reassembly, compression, the TiMS header, delivery to a local
// mailbox, announcements and the discovery table, discover requests). The transport
// is never start()ed and publishes into an LCM log file written to /dev/null, so no
// socket is involved. One input is a sequence of datagrams (2-byte big-endian length,
// then that many bytes) so that reassembly and the discovery table see several.
// Build: this file linked with rack::tims (public headers only; rack_tims links LCM,
// zstd and libsodium). Seeds: tests/fuzz/corpus/lcm_datagram/ (one is a 60 KB chunk:
// -max_len=65536 or more).
#include <cstddef>
#include <cstdint>
#include <memory>

#include "rack/components/class_ids.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/router.h"

namespace {

struct World {
  rack::tims::Router router{0};
  // A mailbox of this host (Generator(0/0)'s command mailbox): messages to it are delivered.
  rack::tims::Mailbox inbox{rack::tims::Address::make(0, rack::class_ids::kGenerator, 0), 64, 64 * 1024};
  std::unique_ptr<rack::tims::LcmTransport> transport;
  World() {
    router.add(inbox);
    rack::tims::LcmTransportConfig c;
    c.url = "file:///dev/null?mode=w";
    c.max_message_bytes = 256 * 1024;  // reassembly of a few chunks, not 4 MB per input
    c.warn = [](const std::string&) {};
    transport = std::make_unique<rack::tims::LcmTransport>(router, c);
    rack::tims::HostInfo self;
    self.host = "fuzz";
    self.executor = rack::tims::Address::make(0, rack::tims::classes::kExecutor, 0);
    self.components.push_back({rack::tims::Address::make(0, rack::class_ids::kGenerator, 0), "generator", "Generator"});
    transport->set_announcement(self);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  static World* world = new World();  // one transport for the process, as in rackd
  for (std::size_t at = 0; at + 2 <= size;) {
    const std::size_t len = (std::size_t{data[at]} << 8) | data[at + 1];
    at += 2;
    const std::size_t n = len < size - at ? len : size - at;
    world->transport->handle_datagram(data + at, n);
    at += n;
  }
  // Drain what was delivered, so the mailbox never stays full.
  while (world->inbox.peek(rack::tims::Mailbox::kNonBlocking).status == rack::tims::RecvStatus::kOk) {
    world->inbox.peek_end();
  }
  return 0;
}
