#include "rack/rt/pm_qos.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace rack::rt {

CpuLatencyHold::CpuLatencyHold(int32_t us) noexcept : us_(us) {
  if (us < 0) return;
  fd_ = ::open("/dev/cpu_dma_latency", O_WRONLY | O_CLOEXEC);
  if (fd_ < 0) {
    errno_ = errno;
    return;
  }
  // The interface takes a binary int32 (or a hex string); the bound lasts while fd_ is open.
  if (::write(fd_, &us, sizeof us) != static_cast<ssize_t>(sizeof us)) {
    errno_ = errno != 0 ? errno : EIO;
    ::close(fd_);
    fd_ = -1;
  }
}

CpuLatencyHold::~CpuLatencyHold() {
  if (fd_ >= 0) ::close(fd_);
}

std::string CpuLatencyHold::describe() const {
  if (us_ < 0) return "CPU idle latency (/dev/cpu_dma_latency): left to the system (cpu_dma_latency_us: -1)";
  if (active()) {
    return "CPU idle latency (/dev/cpu_dma_latency): held at " + std::to_string(us_) + " us while rackd runs";
  }
  return "CPU idle latency: cannot hold /dev/cpu_dma_latency at " + std::to_string(us_) +
         " us: " + std::strerror(errno_) + " (wake-ups from deep idle states will be slower)";
}

}  // namespace rack::rt
