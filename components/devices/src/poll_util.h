// ppoll() with a nanosecond timeout, retrying on EINTR against an absolute deadline.
// RT-safe (one syscall per try).
#pragma once

#include <poll.h>

#include <cerrno>
#include <cstdint>

#include "rack/rt/clock.h"

namespace rack::devices::detail {

// >0: revents set; 0: timeout; <0: -errno.
inline int wait_fd(int fd, short events, int64_t timeout_ns, short& revents) noexcept {
  const int64_t deadline = rack::rt::monotonic_ns() + (timeout_ns > 0 ? timeout_ns : 0);
  for (;;) {
    pollfd p{fd, events, 0};
    int64_t left = deadline - rack::rt::monotonic_ns();
    if (left < 0) left = 0;
    const timespec ts = rack::rt::to_timespec(left);
    const int r = ::ppoll(&p, 1, &ts, nullptr);
    if (r > 0) {
      revents = p.revents;
      return r;
    }
    if (r == 0) return 0;
    if (errno != EINTR) return -errno;
  }
}

}  // namespace rack::devices::detail
