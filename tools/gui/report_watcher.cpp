#include "report_watcher.h"

#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "rack/rt/modeswitch_report.h"

namespace rack::gui {
namespace {

using ReportLineKind = rt::modeswitch::report::LineKind;

// The kind of the report file line bytes[at, nl) (rack/rt/modeswitch_report.h).
ReportLineKind report_line_kind(const std::string& bytes, std::size_t at, std::size_t nl) {
  return rt::modeswitch::report::line_kind(std::string_view(bytes).substr(at, nl - at));
}

}  // namespace

ReportWatcher::ReportWatcher(std::string dir, std::string backtrace_path, Publish publish)
    : dir_(std::move(dir)), backtrace_path_(std::move(backtrace_path)), publish_(std::move(publish)) {}

ReportWatcher::~ReportWatcher() { stop(); }

void ReportWatcher::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] { run(); });
}

void ReportWatcher::stop() {
  running_ = false;
  if (thread_.joinable()) thread_.join();
}

std::string ReportWatcher::snapshot() const {
  const std::lock_guard lock(mutex_);
  return texts_.empty() ? std::string() : message_locked();
}

std::string ReportWatcher::message_locked() const {
  nlohmann::json list = nlohmann::json::array();
  for (const auto& [file, text] : texts_) list.push_back({{"file", file}, {"text", text}});
  return nlohmann::json{{"type", "reports"}, {"dir", dir_}, {"reports", list}}.dump(
      -1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void ReportWatcher::run() {
  std::map<std::string, FileState> seen;
  bool warned = false;
  while (running_.load()) {
    std::error_code ec;
    std::vector<std::filesystem::path> files;
    for (std::filesystem::directory_iterator it(dir_, ec), end; !ec && it != end; it.increment(ec)) {
      const auto name = it->path().filename().string();
      if (name.rfind("rackd-", 0) == 0 && it->path().extension() == ".report") files.push_back(it->path());
    }
    if (ec && !warned && ec != std::errc::no_such_file_or_directory) {
      std::fprintf(stderr, "rack-gui: reports: %s: %s\n", dir_.c_str(), ec.message().c_str());
      warned = true;
    }
    bool changed = false;
    for (const auto& f : files) {
      if (!running_.load()) break;
      std::error_code e1, e2;
      const auto size = std::filesystem::file_size(f, e1);
      const auto mtime = std::filesystem::last_write_time(f, e2);
      if (e1 || e2) continue;
      auto& st = seen[f.string()];
      const bool same = st.size == size && st.mtime == mtime;
      if (same && (st.done >= size || !st.tail_seen)) {
        if (st.done < size) st.tail_seen = true;  // complete it at the next look if it stays so
        continue;
      }
      if (size < st.done) {  // cut or replaced: start again
        st = FileState{};
        const std::lock_guard lock(mutex_);
        texts_.erase(f.string());
      }
      const bool flush_tail = same && st.tail_seen;
      st.size = size;
      st.mtime = mtime;
      const std::size_t before = st.done;
      const auto t0 = std::chrono::steady_clock::now();
      const std::string added = symbolize_new(f.string(), st, flush_tail);
      if (added.empty()) continue;
      const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::fprintf(stderr, "rack-gui: reports: %s: bytes %zu..%zu symbolized in %.2f s\n", f.string().c_str(), before,
                   st.done, took);
      const std::lock_guard lock(mutex_);
      std::string& text = texts_[f.string()];
      text += added;
      if (text.size() > kMaxReportText) {
        std::size_t cut = text.size() - kMaxReportText;
        cut = text.find('\n', cut);
        text = "(older reports left out here: rack-backtrace " + f.string() + " shows them all)\n" +
               (cut == std::string::npos ? std::string() : text.substr(cut + 1));
      }
      changed = true;
    }
    if (changed) {
      std::string m;
      {
        const std::lock_guard lock(mutex_);
        m = message_locked();
      }
      publish_(std::move(m));
    }
    for (int i = 0; i < 20 && running_.load(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

// The part of `file` after st.done up to its last complete report (or to its end
// when `flush_tail`), symbolized; st.done moves past it. "" when nothing new.
std::string ReportWatcher::symbolize_new(const std::string& file, FileState& st, bool flush_tail) {
  std::string bytes;
  {
    std::FILE* in = std::fopen(file.c_str(), "rb");
    if (in == nullptr) return "";
    char buf[65536];
    std::size_t n = 0;
    while ((n = std::fread(buf, 1, sizeof buf, in)) > 0 && bytes.size() < (64u << 20)) bytes.append(buf, n);
    std::fclose(in);
  }
  if (bytes.size() <= st.done) return "";
  // The end of the last complete report ("end N" line) after st.done.
  std::size_t cut = st.done;
  for (std::size_t at = st.done; at < bytes.size();) {
    const auto nl = bytes.find('\n', at);
    if (nl == std::string::npos) break;
    if (report_line_kind(bytes, at, nl) == ReportLineKind::kEnd) cut = nl + 1;
    at = nl + 1;
  }
  if (flush_tail) cut = bytes.size();
  st.tail_seen = cut < bytes.size();
  if (cut == st.done) return "";
  // The header and module lines of the part already done, its other lines blank.
  std::string input;
  input.reserve(cut);
  for (std::size_t at = 0; at < st.done;) {
    auto nl = bytes.find('\n', at);
    if (nl == std::string::npos || nl >= st.done) nl = st.done;
    if (at == 0 || report_line_kind(bytes, at, nl) == ReportLineKind::kModule) input.append(bytes, at, nl - at);
    input += '\n';
    at = nl + 1;
  }
  input.append(bytes, st.done, cut - st.done);
  st.done = cut;
  char tmp[] = "/tmp/rack-gui-report-XXXXXX";
  const int fd = mkstemp(tmp);
  if (fd < 0) return "rack-gui: cannot write a temporary file: " + std::string(std::strerror(errno)) + "\n";
  bool written = true;
  for (std::size_t off = 0; off < input.size();) {
    const ssize_t w = ::write(fd, input.data() + off, input.size() - off);
    if (w <= 0) {
      written = false;
      break;
    }
    off += static_cast<std::size_t>(w);
  }
  ::close(fd);
  std::string out = written ? symbolize(tmp) : "rack-gui: cannot write a temporary file\n";
  ::unlink(tmp);
  // Its name in rack-backtrace's text is the real file's.
  const std::string t = tmp;
  for (auto at = out.find(t); at != std::string::npos; at = out.find(t, at + file.size()))
    out.replace(at, t.size(), file);
  return out;
}

std::string ReportWatcher::backtrace_program() const {
  if (!backtrace_path_.empty()) return backtrace_path_;
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path();
  // Installed: beside rack-gui; in a build tree: tools/rack-backtrace next to tools/gui/.
  for (const auto& candidate : {self / "rack-backtrace", self.parent_path() / "rack-backtrace"}) {
    if (!ec && access(candidate.c_str(), X_OK) == 0) return candidate.string();
  }
  return "rack-backtrace";  // on PATH
}

// rack-backtrace FILE, its output (and errors), at most kMaxReportText. Its own
// process, read with a 100 ms poll: stop() ends it (SIGKILL) instead of waiting for
// it, so rack-gui exits promptly while a large file is being symbolized.
std::string ReportWatcher::symbolize(const std::string& file) const {
  const std::string program = backtrace_program();
  int pipe_fd[2];
  if (pipe(pipe_fd) != 0) return "cannot run rack-backtrace: " + std::string(std::strerror(errno)) + "\n";
  const pid_t pid = fork();
  if (pid < 0) {
    ::close(pipe_fd[0]);
    ::close(pipe_fd[1]);
    return "cannot run rack-backtrace: " + std::string(std::strerror(errno)) + "\n";
  }
  if (pid == 0) {
    ::dup2(pipe_fd[1], 1);
    ::dup2(pipe_fd[1], 2);
    ::close(pipe_fd[0]);
    ::close(pipe_fd[1]);
    const char* argv[] = {program.c_str(), file.c_str(), nullptr};
    ::execvp(argv[0], const_cast<char* const*>(argv));  // NOLINT: execvp's signature
    std::fprintf(stderr, "cannot run %s: %s\n", program.c_str(), std::strerror(errno));
    ::_exit(127);
  }
  ::close(pipe_fd[1]);
  std::string out;
  bool stopped = false;
  for (;;) {
    if (!running_.load()) {
      ::kill(pid, SIGKILL);
      stopped = true;
      break;
    }
    pollfd p{pipe_fd[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, 100);
    if (ready < 0 && errno != EINTR) break;
    if (ready <= 0) continue;
    char buf[4096];
    const ssize_t n = ::read(pipe_fd[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    if (out.size() < kMaxReportText) out.append(buf, static_cast<std::size_t>(n));
  }
  ::close(pipe_fd[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (stopped) return "";
  if (status != 0 && out.empty()) out = "rack-backtrace failed (status " + std::to_string(status) + ")\n";
  return out;
}

}  // namespace rack::gui
