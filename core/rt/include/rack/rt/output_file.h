// Writing files that a later run will trust (key files, traces, graphs): the one place
// that knows how, the counterpart of input_file.h.
//
// - The target, when it exists, must be a regular file: a FIFO (whose open would wait
//   for a reader for ever), a directory, a device or a socket is refused at open(),
//   before anything is done, with what was found.
// - The bytes go to a temporary file in the target's directory (".NAME.tmp.PID.N") and
//   reach the target only at commit(): fsync, then rename over it (or link, for a file
//   that must not replace another). A reader sees the old file or the whole new one,
//   never a part. A write that fails (disk full, a file size limit, I/O error) is said
//   with errno's text and the bytes written; the temporary file is removed then, by
//   discard(), and by the destructor of an OutputFile never committed. (A process
//   killed by a signal leaves its temporary file, named as such, never the target.)
//
// Every error text starts with the path and names the file's role (`what`), e.g.
//   "/tmp/fifo.json: cannot write the trace: it is a FIFO, not a regular file"
//   "keys/net.key: cannot write the key file: No space left on device (after 0 bytes)"
//
// Real-time contract: nothing here is RT-safe (file system calls, allocation in the
// error texts). Tools and set-up code only. Not thread-safe: one owner.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <cstdint>
#include <string>

namespace rack::rt {

enum class OutputMode : uint8_t {
  kReplace,     // replaces an existing regular file; mode 0666 less the umask
  kNewPrivate,  // never replaces a file (it exists: refused, at open() and at commit()); mode 0600
};

class OutputFile {
 public:
  OutputFile() = default;
  ~OutputFile();  // discard() when not committed
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  // Checks the target and creates the temporary file. false with `error` (see above).
  [[nodiscard]] bool open(const std::string& path, const char* what, OutputMode mode, std::string& error);
  [[nodiscard]] bool is_open() const noexcept { return fd_ >= 0; }

  // Appends `n` bytes (retrying short writes and EINTR). false with `error`; the file
  // is discarded then.
  [[nodiscard]] bool write(const void* data, std::size_t n, std::string& error);
  [[nodiscard]] bool write(const std::string& text, std::string& error) {
    return write(text.data(), text.size(), error);
  }
  // fsync, then the temporary file becomes the target. false with `error`; nothing of
  // it is left then, and an existing target is as it was.
  [[nodiscard]] bool commit(std::string& error);
  // Removes the temporary file (nothing reaches the target).
  void discard() noexcept;

  [[nodiscard]] const std::string& path() const noexcept { return path_; }
  // The temporary file, for a program that writes it itself (graphviz' dot -o).
  [[nodiscard]] const std::string& temp_path() const noexcept { return temp_; }
  [[nodiscard]] uint64_t written() const noexcept { return written_; }

 private:
  bool fail(const std::string& why, std::string& error);
  int fd_ = -1;
  std::string path_;
  std::string what_;
  std::string temp_;
  OutputMode mode_ = OutputMode::kReplace;
  uint64_t written_ = 0;
};

}  // namespace rack::rt
