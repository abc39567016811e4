#include "rack/tims/tool_address.h"

#include <fcntl.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "rack/tims/router.h"

namespace rack::tims {

namespace {

constexpr const char* kDefaultRegistry = "/tmp/rack-tool-addresses.lock";

uint32_t random_block() {
  uint32_t r = 0;
  if (getrandom(&r, sizeof r, GRND_NONBLOCK) != static_cast<ssize_t>(sizeof r)) {
    // No entropy yet (early boot): the pid and the clock still differ between tools.
    timespec ts{};
    clock_gettime(CLOCK_REALTIME, &ts);
    r = static_cast<uint32_t>(getpid()) * 2654435761u ^ static_cast<uint32_t>(ts.tv_nsec);
  }
  return r % kToolBlocks;
}

// Open-file-description lock on byte `block`: owned by this descriptor (not the
// process, so two claims in one process exclude each other too), released on close.
bool try_lock(int fd, uint32_t block) {
  struct flock l {};
  l.l_type = F_WRLCK;
  l.l_whence = SEEK_SET;
  l.l_start = static_cast<off_t>(block);
  l.l_len = 1;
  return fcntl(fd, F_OFD_SETLK, &l) == 0;
}

}  // namespace

std::string tool_registry_path() {
  const char* env = std::getenv("RACK_TOOL_REGISTRY");
  return env != nullptr && *env != '\0' ? env : kDefaultRegistry;
}

ToolAddressClaim ToolAddressClaim::claim(const std::string& registry) {
  const std::string path = registry.empty() ? tool_registry_path() : registry;
  const uint32_t start = random_block();
  // O_NOFOLLOW: a symlink planted in /tmp does not redirect us to another file. An
  // existing file is opened without O_CREAT (fs.protected_regular refuses O_CREAT on
  // another user's file in a sticky directory); a new one is made with O_EXCL.
  int fd = -1;
  for (int attempt = 0; attempt < 3 && fd < 0; ++attempt) {
    fd = open(path.c_str(), O_RDWR | O_CLOEXEC | O_NOFOLLOW);
    if (fd < 0 && errno == ENOENT) {
      fd = open(path.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0666);
      if (fd < 0 && errno == EEXIST) continue;  // made by another tool meanwhile
    }
    break;
  }
  if (fd < 0) {
    return ToolAddressClaim(-1, start,
                            "tool address registry " + path + ": " + std::strerror(errno) +
                                "; a random address is used (tools on this machine may collide)");
  }
  struct stat st {};
  if (fstat(fd, &st) == 0 && st.st_uid == geteuid()) (void)fchmod(fd, 0666);  // every user's tools share it
  for (uint32_t i = 0; i < kToolBlocks; ++i) {
    const uint32_t block = (start + i) % kToolBlocks;
    if (try_lock(fd, block)) return ToolAddressClaim(fd, block, "");
    if (errno != EAGAIN && errno != EACCES) {
      const std::string why = std::strerror(errno);
      close(fd);
      return ToolAddressClaim(-1, start,
                              "tool address registry " + path + ": cannot lock: " + why +
                                  "; a random address is used (tools on this machine may collide)");
    }
  }
  close(fd);
  throw std::runtime_error("every one of the " + std::to_string(kToolBlocks) + " tool addresses is claimed in " + path);
}

ToolAddressClaim::ToolAddressClaim(ToolAddressClaim&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), block_(other.block_), warning_(std::move(other.warning_)) {}

ToolAddressClaim& ToolAddressClaim::operator=(ToolAddressClaim&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) close(fd_);
    fd_ = std::exchange(other.fd_, -1);
    block_ = other.block_;
    warning_ = std::move(other.warning_);
  }
  return *this;
}

ToolAddressClaim::~ToolAddressClaim() {
  if (fd_ >= 0) close(fd_);
}

Address ToolAddressClaim::mailbox(uint32_t index) const noexcept {
  constexpr uint32_t kBlocksPerInstance = 256 / kToolMailboxes;
  const auto instance = static_cast<uint8_t>(block_ / kBlocksPerInstance);
  const auto local = static_cast<uint8_t>((block_ % kBlocksPerInstance) * kToolMailboxes + index % kToolMailboxes);
  return Address::make(kToolSystem, classes::kTool, instance, local);
}

}  // namespace rack::tims
