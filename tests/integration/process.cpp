#include "process.h"

#include <fcntl.h>
#include <poll.h>
#include <sched.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

namespace rack::test {

namespace {

// Children alive right now, for the watchdog.
std::mutex g_children_mutex;
std::set<pid_t> g_children;

void register_child(pid_t pid) {
  std::lock_guard lock(g_children_mutex);
  g_children.insert(pid);
}
void unregister_child(pid_t pid) {
  std::lock_guard lock(g_children_mutex);
  g_children.erase(pid);
}

std::vector<char*> make_argv(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  return argv;
}

// In the child between fork and exec: only async-signal-safe calls.
[[noreturn]] void exec_child(char* const* argv, pid_t parent, int out_fd, int err_fd, int netns_fd) {
  prctl(PR_SET_PDEATHSIG, SIGKILL);  // dies with the test process
  if (getppid() != parent) _exit(127);
  if (netns_fd >= 0 && setns(netns_fd, CLONE_NEWNET) != 0) _exit(126);
  const int null_fd = open("/dev/null", O_RDONLY);
  if (null_fd >= 0) dup2(null_fd, STDIN_FILENO);
  dup2(out_fd, STDOUT_FILENO);
  dup2(err_fd, STDERR_FILENO);
  // Signals blocked or ignored by the test runner must not leak into the child.
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);
  signal(SIGPIPE, SIG_DFL);
  execv(argv[0], argv);
  _exit(127);
}

int decode_status(int status, int& term_signal) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) term_signal = WTERMSIG(status);
  return -1;
}

// The namespace's file, opened before fork (the child only calls setns on it).
int open_netns(const std::string& netns) {
  if (netns.empty()) return -1;
  const std::string path = "/run/netns/" + netns;
  const int fd = open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error("cannot open network namespace " + path + ": " + std::strerror(errno));
  return fd;
}

int64_t now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

std::string RunResult::describe() const {
  std::ostringstream s;
  s << "exit code " << exit_code;
  if (term_signal != 0) s << " (signal " << term_signal << ")";
  if (timed_out) s << " (timed out, killed)";
  s << "\n--- stdout ---\n" << out << "--- stderr ---\n" << err << "---";
  return s.str();
}

RunResult run(const std::vector<std::string>& args, std::chrono::milliseconds timeout, const std::string& netns) {
  RunResult result;
  const int netns_fd = open_netns(netns);
  int out_pipe[2];
  int err_pipe[2];
  if (pipe2(out_pipe, O_CLOEXEC) != 0 || pipe2(err_pipe, O_CLOEXEC) != 0) {
    throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  }
  auto argv = make_argv(args);
  const pid_t parent = getpid();
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) exec_child(argv.data(), parent, out_pipe[1], err_pipe[1], netns_fd);
  register_child(pid);
  if (netns_fd >= 0) close(netns_fd);
  close(out_pipe[1]);
  close(err_pipe[1]);

  pollfd fds[2] = {{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}};
  std::string* sinks[2] = {&result.out, &result.err};
  bool open_fds[2] = {true, true};
  const int64_t deadline = now_ms() + timeout.count();
  bool exited = false;
  int status = 0;
  while (!exited || open_fds[0] || open_fds[1]) {
    const int64_t left = deadline - now_ms();
    if (left <= 0) {
      result.timed_out = true;
      kill(pid, SIGKILL);
      break;
    }
    for (int i = 0; i < 2; ++i) fds[i].fd = open_fds[i] ? (i == 0 ? out_pipe[0] : err_pipe[0]) : -1;
    const int rc = poll(fds, 2, static_cast<int>(std::min<int64_t>(left, 50)));
    if (rc > 0) {
      for (int i = 0; i < 2; ++i) {
        if (fds[i].fd < 0 || (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
        char buf[4096];
        const ssize_t n = read(fds[i].fd, buf, sizeof buf);
        if (n > 0) sinks[i]->append(buf, static_cast<std::size_t>(n));
        else if (n == 0 || errno != EINTR) open_fds[i] = false;
      }
    }
    if (!exited && waitpid(pid, &status, WNOHANG) == pid) exited = true;
  }
  if (!exited) waitpid(pid, &status, 0);
  unregister_child(pid);
  close(out_pipe[0]);
  close(err_pipe[0]);
  result.exit_code = decode_status(status, result.term_signal);
  return result;
}

Process::Process(const std::vector<std::string>& args, const std::filesystem::path& dir, const std::string& tag,
                 const std::string& netns)
    : out_path_(dir / (tag + ".stdout")), err_path_(dir / (tag + ".stderr")) {
  const int netns_fd = open_netns(netns);
  const int out_fd = open(out_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  const int err_fd = open(err_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (out_fd < 0 || err_fd < 0) throw std::runtime_error("cannot create output files in " + dir.string());
  auto argv = make_argv(args);
  const pid_t parent = getpid();
  pid_ = fork();
  if (pid_ < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid_ == 0) exec_child(argv.data(), parent, out_fd, err_fd, netns_fd);
  register_child(pid_);
  if (netns_fd >= 0) close(netns_fd);
  close(out_fd);
  close(err_fd);
}

Process::~Process() {
  if (!status_ && pid_ > 0) {
    kill(pid_, SIGKILL);
    int status = 0;
    waitpid(pid_, &status, 0);
    unregister_child(pid_);
  }
}

bool Process::running() {
  if (status_) return false;
  int status = 0;
  if (waitpid(pid_, &status, WNOHANG) == pid_) {
    int sig = 0;
    status_ = decode_status(status, sig);
    term_signal_ = sig;
    unregister_child(pid_);
    return false;
  }
  return true;
}

bool Process::wait_for_stderr(const std::string& text, std::chrono::milliseconds timeout) {
  const int64_t deadline = now_ms() + timeout.count();
  for (;;) {
    if (err().find(text) != std::string::npos) return true;
    if (!running() || now_ms() >= deadline) return err().find(text) != std::string::npos;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

void Process::signal(int sig) {
  if (running()) kill(pid_, sig);
}

std::optional<int> Process::wait_exit(std::chrono::milliseconds timeout) {
  const int64_t deadline = now_ms() + timeout.count();
  while (running()) {
    if (now_ms() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return status_;
}

std::string Process::out() const { return read_file(out_path_); }
std::string Process::err() const { return read_file(err_path_); }

Watchdog::Watchdog(std::chrono::seconds limit, std::string what) {
  thread_ = std::thread([this, limit, what = std::move(what)] {
    std::unique_lock lock(mutex_);
    if (cv_.wait_for(lock, limit, [this] { return done_; })) return;
    std::fprintf(stderr, "WATCHDOG: %s ran longer than %lld s: killing its children and aborting\n", what.c_str(),
                 static_cast<long long>(limit.count()));
    {
      std::lock_guard children(g_children_mutex);
      for (const pid_t pid : g_children) kill(pid, SIGKILL);
    }
    std::fflush(stderr);
    std::_Exit(3);
  });
}

Watchdog::~Watchdog() {
  {
    std::lock_guard lock(mutex_);
    done_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

LcmBus::LcmBus() {
  // Ports 17700..21699; start at a place that depends on the pid so parallel test
  // processes rarely probe the same ports, and lock the one we take.
  constexpr int kBase = 17700;
  constexpr int kSpan = 4000;
  const std::filesystem::path dir = std::filesystem::temp_directory_path();
  const int start = static_cast<int>((static_cast<unsigned>(getpid()) * 37u) % kSpan);
  for (int i = 0; i < kSpan; ++i) {
    const int port = kBase + (start + i) % kSpan;
    const auto lock_path = dir / ("rack-integration-lcm-" + std::to_string(port) + ".lock");
    const int fd = open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
    if (fd < 0) continue;
    if (flock(fd, LOCK_EX | LOCK_NB) == 0) {
      fd_ = fd;
      port_ = port;
      return;
    }
    close(fd);
  }
  throw std::runtime_error("no free LCM port for the test");
}

LcmBus::~LcmBus() {
  if (fd_ >= 0) close(fd_);  // releases the lock
}

std::string LcmBus::url() const { return "udpm://239.255.76.67:" + std::to_string(port_) + "?ttl=0"; }

TempDir::TempDir() {
  std::string pattern = (std::filesystem::temp_directory_path() / "rack-it-XXXXXX").string();
  if (mkdtemp(pattern.data()) == nullptr) throw std::runtime_error(std::string("mkdtemp: ") + std::strerror(errno));
  path_ = pattern;
}

TempDir::~TempDir() {
  std::error_code ec;
  std::filesystem::remove_all(path_, ec);
}

std::filesystem::path TempDir::write(const std::string& name, const std::string& text) const {
  const auto p = path_ / name;
  std::ofstream f(p);
  f << text;
  if (!f) throw std::runtime_error("cannot write " + p.string());
  return p;
}

std::optional<std::string> find_program(const std::string& name) {
  const char* path = std::getenv("PATH");
  const std::string p = path != nullptr ? path : "/usr/bin:/bin";
  std::size_t start = 0;
  while (start <= p.size()) {
    const auto end = p.find(':', start);
    const std::string dir = p.substr(start, end == std::string::npos ? std::string::npos : end - start);
    const std::string candidate = (dir.empty() ? "." : dir) + "/" + name;
    if (access(candidate.c_str(), X_OK) == 0) return candidate;
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return std::nullopt;
}

BrowserTools find_browser_tools() {
  BrowserTools t;
  const char* chromium = std::getenv("RACK_CHROMIUM");
  t.chromium = chromium != nullptr ? chromium : "/usr/bin/chromium";
  if (const auto node = find_program("node")) {
    t.node = *node;
  } else {
    t.missing = "node is not installed (Debian: apt-get install nodejs); scripts/setup.sh installs it";
    return t;
  }
  if (access(t.chromium.c_str(), X_OK) != 0) {
    t.missing = t.chromium + " is not installed (Debian: apt-get install chromium); scripts/setup.sh installs it";
  }
  return t;
}

std::string served_url(Process& gui, std::chrono::milliseconds timeout) {
  const std::string said = "rack-gui: serving ";
  if (!gui.wait_for_stderr(said + "http://", timeout)) return "";
  const std::string err = gui.err();
  const auto at = err.find(said) + said.size();
  return err.substr(at, err.find_first_of(" \n", at) - at);
}

uint16_t port_of(const std::string& url) {
  const auto host = url.find("://");
  const auto colon = url.find(':', host == std::string::npos ? 0 : host + 3);
  if (host == std::string::npos || colon == std::string::npos) return 0;
  const long port = std::strtol(url.c_str() + colon + 1, nullptr, 10);
  return port > 0 && port <= 65535 ? static_cast<uint16_t>(port) : 0;
}

std::string read_file(const std::filesystem::path& path) {
  std::ifstream f(path);
  std::stringstream s;
  s << f.rdbuf();
  return s.str();
}

}  // namespace rack::test
