// Addresses of tools (rackctl, rack-gui, bench tools): each running tool holds a block
// of kToolMailboxes mailbox addresses on the tool system (kToolSystem, class kTool)
// that no other tool holds at the same time.
//
// Why: replies are routed by address only. Two tools with the same address receive
// each other's replies (a reply to one is taken as the other's answer when source and
// sequence number match, or fills its mailbox), and each one's requests are dropped as
// forged by the other's transport. The old pid-derived addresses collided for tools
// started back to back.
//
// How:
//  - on one machine, a registry file (default /tmp/rack-tool-addresses.lock, or
//    $RACK_TOOL_REGISTRY): the block is claimed with an open-file-description lock on
//    the byte at the block's index (fcntl F_OFD_SETLK). The kernel releases it when the
//    process ends in any way (SIGKILL included), so there are no stale claims and no
//    clean-up. Any number of tools started at once get distinct blocks (up to
//    kToolBlocks at the same time).
//  - across machines on one network: the search starts at a random block (getrandom),
//    so two machines collide only when their tools pick the same one of kToolBlocks
//    blocks (1 in 16320 for one pair). A collision is not silent: each transport drops
//    and reports the other's packets as "forged" (a message whose source is one of its
//    own mailboxes).
//  - when the registry cannot be used (no writable /tmp), the block is random and a
//    warning says why (`warning()`).
//
// Not RT code (set-up of a tool). Thread-safety: claim() may be called from any
// thread; a claim is owned by one object (move-only).
#pragma once

#include <cstdint>
#include <string>
#include <utility>

#include "rack/tims/address.h"

namespace rack::tims {

inline constexpr uint32_t kToolMailboxes = 4;  // mailboxes per tool: local index 0..3
// Instances 0..254 (255 is the transports' own: uplinks, control) x 64 blocks of 4.
inline constexpr uint32_t kToolBlocks = 255 * (256 / kToolMailboxes);

// The default registry path (or $RACK_TOOL_REGISTRY when set and not empty).
[[nodiscard]] std::string tool_registry_path();

class ToolAddressClaim {
 public:
  // Claims a free block. `registry`: the registry file ("" = tool_registry_path()).
  // Never fails: without a usable registry the block is random (see warning()).
  // Throws std::runtime_error only when every block is claimed on this machine.
  static ToolAddressClaim claim(const std::string& registry = "");

  ToolAddressClaim(ToolAddressClaim&& other) noexcept;
  ToolAddressClaim& operator=(ToolAddressClaim&& other) noexcept;
  ToolAddressClaim(const ToolAddressClaim&) = delete;
  ToolAddressClaim& operator=(const ToolAddressClaim&) = delete;
  ~ToolAddressClaim();  // releases the block

  // The address of local mailbox `index` (< kToolMailboxes) of this tool.
  [[nodiscard]] Address mailbox(uint32_t index) const noexcept;
  [[nodiscard]] uint32_t block() const noexcept { return block_; }
  // Why the block is not registered ("" when it is).
  [[nodiscard]] const std::string& warning() const noexcept { return warning_; }

 private:
  ToolAddressClaim(int fd, uint32_t block, std::string warning) noexcept
      : fd_(fd), block_(block), warning_(std::move(warning)) {}
  int fd_ = -1;
  uint32_t block_ = 0;
  std::string warning_;
};

}  // namespace rack::tims
