#include "rack/rt/input_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

namespace rack::rt {

namespace {

const char* or_file(const char* what) noexcept { return what != nullptr && *what != '\0' ? what : "file"; }

std::string errno_text(int e) { return std::strerror(e); }

}  // namespace

const char* file_kind_text(mode_t mode) noexcept {
  if (S_ISREG(mode)) return "a regular file";
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISLNK(mode)) return "a symbolic link";
  return "of an unknown file type";
}

std::string byte_size_text(uint64_t bytes) {
  static constexpr const char* kUnits[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  if (bytes < 1024) return std::to_string(bytes) + " B";
  double v = static_cast<double>(bytes);
  std::size_t u = 0;
  while (v >= 1024.0 && u + 1 < sizeof kUnits / sizeof kUnits[0]) {
    v /= 1024.0;
    ++u;
  }
  char buf[32];
  if (v == static_cast<double>(static_cast<uint64_t>(v))) {
    std::snprintf(buf, sizeof buf, "%llu %s", static_cast<unsigned long long>(v), kUnits[u]);
  } else {
    std::snprintf(buf, sizeof buf, "%.1f %s", v, kUnits[u]);
  }
  return buf;
}

InputFile::~InputFile() { close(); }

InputFile::InputFile(InputFile&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)),
      path_(std::move(other.path_)),
      what_(std::move(other.what_)),
      size_(other.size_),
      offset_(other.offset_),
      limit_(other.limit_),
      mode_(other.mode_) {}

InputFile& InputFile::operator=(InputFile&& other) noexcept {
  if (this != &other) {
    close();
    fd_ = std::exchange(other.fd_, -1);
    path_ = std::move(other.path_);
    what_ = std::move(other.what_);
    size_ = other.size_;
    offset_ = other.offset_;
    limit_ = other.limit_;
    mode_ = other.mode_;
  }
  return *this;
}

void InputFile::close() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

bool InputFile::open(const std::string& path, uint64_t max_bytes, const char* what, std::string& error) {
  close();
  path_ = path;
  what_ = what != nullptr ? what : "";
  size_ = offset_ = 0;
  limit_ = max_bytes;
  if (path.empty()) {
    error = std::string("(empty path): no ") + or_file(what) + " named";
    return false;
  }
  if (path.find('\0') != std::string::npos) {
    error = path.substr(0, path.find('\0')) + ": the path of the " + or_file(what) + " holds a NUL byte";
    return false;
  }
  // O_NONBLOCK: opening a FIFO for reading otherwise waits for a writer (for ever);
  // O_NOCTTY: a terminal named by mistake must not become our controlling terminal.
  // Both are harmless for the regular file that passes the check below.
  int fd = -1;
  do {
    fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  } while (fd < 0 && errno == EINTR);
  if (fd < 0) {
    error = path + ": cannot open the " + or_file(what) + ": " + errno_text(errno);
    return false;
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    error = path + ": cannot stat the " + or_file(what) + ": " + errno_text(e);
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    error = path + ": the " + or_file(what) + " is " + file_kind_text(st.st_mode) + ", not a regular file";
    return false;
  }
  const uint64_t size = st.st_size > 0 ? static_cast<uint64_t>(st.st_size) : 0;
  if (size > max_bytes) {
    ::close(fd);
    error = path + ": the " + or_file(what) + " has " + byte_size_text(size) + ", more than the limit of " +
            byte_size_text(max_bytes);
    return false;
  }
  // Back to blocking reads: a regular file's reads never wait on a writer anyway.
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) (void)::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  fd_ = fd;
  size_ = size;
  mode_ = st.st_mode;
  return true;
}

long InputFile::read(void* buffer, std::size_t n, std::string& error) {
  if (fd_ < 0) {
    error = (path_.empty() ? std::string("(no file)") : path_) + ": the " + or_file(what_.c_str()) + " is not open";
    return -1;
  }
  auto* out = static_cast<unsigned char*>(buffer);
  std::size_t got = 0;
  while (got < n) {
    // One byte beyond the limit is asked for, so that a file that grew past it is seen.
    const uint64_t left = limit_ - offset_;  // offset_ <= limit_ here (checked after each read)
    const uint64_t allowed = left == UINT64_MAX ? left : left + 1;
    const std::size_t want = static_cast<std::size_t>(std::min<uint64_t>(n - got, allowed));
    if (want == 0) break;
    const ssize_t r = ::read(fd_, out + got, want);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      error = path_ + ": byte " + std::to_string(offset_) + ": cannot read the " + or_file(what_.c_str()) + ": " +
              errno_text(errno);
      return -1;
    }
    if (r == 0) break;
    got += static_cast<std::size_t>(r);
    offset_ += static_cast<uint64_t>(r);
    if (offset_ > limit_) {
      error = path_ + ": byte " + std::to_string(limit_) + ": the " + or_file(what_.c_str()) +
              " grew past the limit of " + byte_size_text(limit_) + " while being read";
      return -1;
    }
  }
  return static_cast<long>(got);
}

bool InputFile::read_all(std::string& out, std::string& error) {
  out.clear();
  // The size fstat gave is a hint only (the file may shrink, grow, or say 0).
  out.reserve(static_cast<std::size_t>(std::min<uint64_t>(remaining(), limit_)));
  char chunk[65536];
  for (;;) {
    const long n = read(chunk, sizeof chunk, error);
    if (n < 0) {
      out.clear();
      return false;
    }
    if (n == 0) return true;
    out.append(chunk, static_cast<std::size_t>(n));
  }
}

bool read_regular_file(const std::string& path, uint64_t max_bytes, const char* what, std::string& out,
                       std::string& error) {
  out.clear();
  InputFile f;
  return f.open(path, max_bytes, what, error) && f.read_all(out, error);
}

bool check_regular_file(const std::string& path, uint64_t max_bytes, const char* what, std::string& error) {
  struct stat st {};
  if (path.empty()) {
    error = std::string("(empty path): no ") + or_file(what) + " named";
    return false;
  }
  if (::stat(path.c_str(), &st) != 0) {
    error = path + ": cannot open the " + or_file(what) + ": " + errno_text(errno);
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    error = path + ": the " + or_file(what) + " is " + file_kind_text(st.st_mode) + ", not a regular file";
    return false;
  }
  const uint64_t size = st.st_size > 0 ? static_cast<uint64_t>(st.st_size) : 0;
  if (size > max_bytes) {
    error = path + ": the " + or_file(what) + " has " + byte_size_text(size) + ", more than the limit of " +
            byte_size_text(max_bytes);
    return false;
  }
  return true;
}

namespace {

bool check_kind(const std::string& path, bool (*is)(mode_t), const char* expected, const char* what,
                std::string& error) {
  struct stat st {};
  if (path.empty()) {
    error = std::string("(empty path): no ") + or_file(what) + " named";
    return false;
  }
  if (::stat(path.c_str(), &st) != 0) {
    error = path + ": cannot open the " + or_file(what) + ": " + errno_text(errno);
    return false;
  }
  if (!is(st.st_mode)) {
    error = path + ": the " + or_file(what) + " is " + file_kind_text(st.st_mode) + ", not " + expected;
    return false;
  }
  return true;
}

}  // namespace

bool check_char_device(const std::string& path, const char* what, std::string& error) {
  return check_kind(
      path, [](mode_t m) { return S_ISCHR(m); }, "a character device", what, error);
}

bool check_socket(const std::string& path, const char* what, std::string& error) {
  return check_kind(
      path, [](mode_t m) { return S_ISSOCK(m); }, "a socket", what, error);
}

}  // namespace rack::rt
