// A pseudo-terminal standing in for a serial device, with an optional stable symlink
// (as udev gives real devices). Shared by the serial simulators. Not RT code.
#pragma once

#include <fcntl.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <string>
#include <system_error>

namespace rack::sims::detail {

class PtyDevice {
 public:
  explicit PtyDevice(std::string link) : link_(std::move(link)) {}
  ~PtyDevice() { close(); }
  PtyDevice(const PtyDevice&) = delete;
  PtyDevice& operator=(const PtyDevice&) = delete;

  // A new pty; the symlink (if any) moves to it atomically. Throws std::system_error.
  void open() {
    close();
    int master = -1, slave = -1;
    char name[256];
    if (::openpty(&master, &slave, name, nullptr, nullptr) != 0) {
      throw std::system_error(errno, std::generic_category(), "openpty");
    }
    termios t{};
    ::tcgetattr(slave, &t);
    ::cfmakeraw(&t);  // no echo, no CR/LF translation: bytes as a UART carries them
    ::tcsetattr(slave, TCSANOW, &t);
    ::fcntl(master, F_SETFD, FD_CLOEXEC);
    ::fcntl(slave, F_SETFD, FD_CLOEXEC);
    // Non-blocking: with no reader the pty fills up; a simulator must never hang on it.
    ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
    master_ = master;
    slave_keep_ = slave;  // held open so writes do not fail before a driver opens it
    slave_path_ = name;
    if (!link_.empty()) {
      const std::string tmp = link_ + ".new";
      std::filesystem::remove(tmp);
      std::filesystem::create_symlink(slave_path_, tmp);
      std::filesystem::rename(tmp, link_);
    }
  }
  void close() {
    if (master_ >= 0) ::close(master_);
    if (slave_keep_ >= 0) ::close(slave_keep_);
    master_ = slave_keep_ = -1;
  }
  void remove_link() {
    std::error_code ec;
    if (!link_.empty()) std::filesystem::remove(link_, ec);
  }
  [[nodiscard]] int master() const { return master_; }
  [[nodiscard]] std::string device() const { return link_.empty() ? slave_path_ : link_; }

 private:
  std::string link_;
  std::string slave_path_;
  int master_ = -1;
  int slave_keep_ = -1;
};

}  // namespace rack::sims::detail
