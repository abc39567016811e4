#include "rack/rt/output_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>

#include "rack/rt/input_file.h"

namespace rack::rt {

namespace {

// A temporary name no other OutputFile of this process uses (with the pid: of this machine).
unsigned next_temp_number() noexcept {
  static std::atomic<unsigned> n{0};  // relaxed: only uniqueness matters
  return n.fetch_add(1, std::memory_order_relaxed);
}

// Makes the rename durable: the directory entry, not only the file's bytes. Best
// effort (a file system may refuse fsync on a directory).
void sync_directory(const std::string& dir) noexcept {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  (void)::fsync(fd);
  ::close(fd);
}

}  // namespace

OutputFile::~OutputFile() { discard(); }

bool OutputFile::fail(const std::string& why, std::string& error) {
  error = path_ + ": cannot write the " + what_ + ": " + why;
  discard();
  return false;
}

bool OutputFile::open(const std::string& path, const char* what, OutputMode mode, std::string& error) {
  discard();
  path_ = path;
  what_ = what != nullptr && *what != '\0' ? what : "file";
  mode_ = mode;
  written_ = 0;
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (!S_ISREG(st.st_mode))
      return fail(std::string("it is ") + file_kind_text(st.st_mode) + ", not a regular file", error);
    if (mode == OutputMode::kNewPrivate) return fail("it exists (not overwritten)", error);
  } else if (errno != ENOENT) {
    return fail(std::strerror(errno), error);
  }
  const auto slash = path.rfind('/');
  const std::string dir = slash == std::string::npos ? "" : path.substr(0, slash + 1);
  std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
  if (base.empty()) return fail("it names a directory, not a file", error);
  if (base.size() > 200) base.resize(200);  // the temporary name stays within NAME_MAX (255)
  const mode_t perms = mode == OutputMode::kNewPrivate ? 0600 : 0666;
  for (int attempt = 0; attempt < 100; ++attempt) {
    temp_ = dir + "." + base + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(next_temp_number());
    fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, perms);
    if (fd_ >= 0) break;
    if (errno != EEXIST) break;
  }
  if (fd_ < 0) {
    const int e = errno;
    temp_.clear();  // not ours: never removed
    return fail(std::strerror(e), error);
  }
  // Exactly 0600 for a private file, whatever the umask did.
  if (mode == OutputMode::kNewPrivate && ::fchmod(fd_, 0600) != 0) return fail(std::strerror(errno), error);
  return true;
}

bool OutputFile::write(const void* data, std::size_t n, std::string& error) {
  if (fd_ < 0) return fail("not open", error);
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    const ssize_t k = ::write(fd_, p, n);
    if (k < 0 && errno == EINTR) continue;
    if (k <= 0) {
      const int e = k < 0 ? errno : ENOSPC;
      return fail(std::string(std::strerror(e)) + " (after " + std::to_string(written_) + " bytes)", error);
    }
    p += k;
    n -= static_cast<std::size_t>(k);
    written_ += static_cast<uint64_t>(k);
  }
  return true;
}

bool OutputFile::commit(std::string& error) {
  if (fd_ < 0) return fail("not open", error);
  if (::fsync(fd_) != 0) return fail(std::string("fsync: ") + std::strerror(errno), error);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) return fail(std::string("close: ") + std::strerror(errno), error);
  if (mode_ == OutputMode::kNewPrivate) {
    // link() fails with EEXIST when the target appeared meanwhile: never replaced.
    if (::link(temp_.c_str(), path_.c_str()) != 0) {
      const int e = errno;
      return fail(e == EEXIST ? std::string("it exists (not overwritten)") : std::string("link: ") + std::strerror(e),
                  error);
    }
    ::unlink(temp_.c_str());
  } else if (::rename(temp_.c_str(), path_.c_str()) != 0) {
    return fail(std::string("rename: ") + std::strerror(errno), error);
  }
  temp_.clear();
  const auto slash = path_.rfind('/');
  sync_directory(slash == std::string::npos ? "" : path_.substr(0, slash + 1));
  return true;
}

void OutputFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temp_.empty()) ::unlink(temp_.c_str());
  temp_.clear();
}

}  // namespace rack::rt
