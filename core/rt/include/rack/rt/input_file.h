// Opening files and devices named by outside input (host files, maps, logs, key files,
// point clouds, records, reports), the one place that knows how to do it safely:
//
// - A path where a regular file is expected is opened with O_NONBLOCK (so a FIFO
//   cannot block the open) and checked on the descriptor (fstat of what was opened, no
//   race with a rename): a FIFO, socket, directory or device is refused, and so is a
//   file larger than the caller's limit, before anything is allocated for it.
// - Reading stops at the limit even when the file grows, or when its size said
//   nothing (files in /proc report 0): no reader allocates more than its limit.
// - A path where a device is expected (a serial port, /dev/input/js0) must be a
//   character device: a regular file or FIFO put there by mistake is refused.
//
// Every error text starts with the path, names the file's role (`what`: "map image",
// "key file"), and says what was expected, what was found, or errno's text, e.g.
//   "maps/office.pgm: the map image is a FIFO, not a regular file"
//   "/tmp/big.pcd: the PCD file has 3.2 GiB, more than the limit of 256 MiB"
//   "/tmp/x.log: cannot open the log file: No such file or directory"
//
// Real-time contract: nothing here is RT-safe (open, fstat, read; allocation in
// read_regular_file and in the error texts). Set-up code and non-RT threads only.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <string>

namespace rack::rt {

// "a FIFO", "a directory", "a character device", ... for an st_mode (messages).
[[nodiscard]] const char* file_kind_text(mode_t mode) noexcept;
// "512 B", "64 KiB", "1.5 GiB" (messages).
[[nodiscard]] std::string byte_size_text(uint64_t bytes);

// A regular file opened for reading, no larger than a limit: a bounded stream.
// Not copyable; closes its descriptor when destroyed.
class InputFile {
 public:
  InputFile() = default;
  ~InputFile();
  InputFile(const InputFile&) = delete;
  InputFile& operator=(const InputFile&) = delete;
  InputFile(InputFile&& other) noexcept;
  InputFile& operator=(InputFile&& other) noexcept;

  // Opens `path` for reading. false with `error` ("path: ...", see above) when it cannot
  // be opened, is not a regular file, or is larger than `max_bytes`.
  [[nodiscard]] bool open(const std::string& path, uint64_t max_bytes, const char* what, std::string& error);
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }
  void close() noexcept;

  // Reads up to `n` bytes into `buffer`, retrying on EINTR and short reads until `n`
  // bytes, the end of the file, or the limit. Returns the bytes read (0 at the end).
  // -1 with `error` = "path: byte OFFSET: reason" when read() fails or the file grew
  // past the limit since it was opened.
  [[nodiscard]] long read(void* buffer, std::size_t n, std::string& error);
  // Reads the rest of the file (up to the limit) into `out`. false with `error`.
  [[nodiscard]] bool read_all(std::string& out, std::string& error);

  [[nodiscard]] const std::string& path() const noexcept { return path_; }
  // The size fstat reported at open() (0 for files whose size says nothing, as in /proc).
  [[nodiscard]] uint64_t size() const noexcept { return size_; }
  // Bytes read so far: the offset of the next byte.
  [[nodiscard]] uint64_t offset() const noexcept { return offset_; }
  // Bytes left before the end as fstat reported it (0 once past it).
  [[nodiscard]] uint64_t remaining() const noexcept { return offset_ < size_ ? size_ - offset_ : 0; }
  [[nodiscard]] uint64_t limit() const noexcept { return limit_; }
  // The file's st_mode at open() (permission checks: key files must not be readable by others).
  [[nodiscard]] mode_t mode() const noexcept { return mode_; }
  // The descriptor (for fstat and the like); -1 when not open. Still owned by this object.
  [[nodiscard]] int fd() const noexcept { return fd_; }

 private:
  int fd_ = -1;
  std::string path_;
  std::string what_;
  uint64_t size_ = 0;
  uint64_t offset_ = 0;
  uint64_t limit_ = 0;
  mode_t mode_ = 0;
};

// Reads a whole regular file of at most `max_bytes` into `out`. false with `error`
// ("path: ..."); `out` is then empty.
[[nodiscard]] bool read_regular_file(const std::string& path, uint64_t max_bytes, const char* what, std::string& out,
                                     std::string& error);

// For paths handed to a library that opens them itself (dlopen, MRPT, OpenCV): true
// when `path` is a regular file of at most `max_bytes` at the moment of the check
// (stat follows symbolic links, as the library's open will). false with `error`.
// The library opens the file again, so a file swapped in between is not caught: use
// InputFile wherever the bytes can be read here.
[[nodiscard]] bool check_regular_file(const std::string& path, uint64_t max_bytes, const char* what,
                                      std::string& error);

// For paths that must name a character device (a serial port, a joystick, a video
// device): false with `error` = "path: the serial port is a regular file, not a
// character device", or errno's text when it does not exist.
[[nodiscard]] bool check_char_device(const std::string& path, const char* what, std::string& error);

// For paths that must name a Unix socket (a simulated CAN bus): as check_char_device.
[[nodiscard]] bool check_socket(const std::string& path, const char* what, std::string& error);

}  // namespace rack::rt
