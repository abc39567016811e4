#include "class_info.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>

#include <nlohmann/json.hpp>

namespace rack::tools {

std::string rackd_beside_me() {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec).parent_path();
  if (!ec) {
    for (const auto& candidate : {self / "rackd", self.parent_path() / "rackd"}) {
      if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
  }
  return "rackd";
}

bool parse_class_list(const std::string& json_text, std::vector<rack::deploy::ClassInfo>& out, std::string& why) {
  const nlohmann::json j = nlohmann::json::parse(json_text, nullptr, false);
  if (!j.is_array()) {
    why = "not a JSON array of classes";
    return false;
  }
  for (const auto& c : j) {
    if (!c.is_object() || !c.contains("impl") || !c["impl"].is_string()) {
      why = "a class without \"impl\"";
      return false;
    }
    rack::deploy::ClassInfo ci;
    ci.impl = c["impl"].get<std::string>();
    if (c.contains("class") && c["class"].is_string()) ci.class_name = c["class"].get<std::string>();
    if (const auto id = c.find("class_id"); id != c.end() && id->is_number_integer()) {
      const auto v = id->get<int64_t>();
      if (v > 0 && v < 256) ci.class_id = static_cast<int>(v);
    }
    if (const auto p = c.find("parameters"); p != c.end() && p->is_array()) {
      ci.described = true;
      for (const auto& prm : *p) {
        // Only a true boolean marks a reference (json::value() would throw on another type).
        const auto ref = prm.is_object() ? prm.find("component_ref") : prm.end();
        if (ref != prm.end() && ref->is_boolean() && ref->get<bool>() && prm.contains("name") &&
            prm["name"].is_string()) {
          ci.refs.push_back(prm["name"].get<std::string>());
        }
      }
    }
    out.push_back(std::move(ci));
  }
  return true;
}

bool classes_from_rackd(const std::string& rackd, std::vector<rack::deploy::ClassInfo>& out, std::string& why,
                        int timeout_ms, const std::vector<std::string>& host_files) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    why = std::string("pipe: ") + std::strerror(errno);
    return false;
  }
  std::vector<std::string> args{rackd, "--list-classes", "--json"};
  for (const auto& f : host_files) {
    if (!f.empty() && f[0] == '-') args.push_back("./" + f);  // a file, never an option
    else args.push_back(f);
  }
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    why = std::string("fork: ") + std::strerror(errno);
    return false;
  }
  if (pid == 0) {  // async-signal-safe calls only, then exec
    const int devnull = ::open("/dev/null", O_RDWR);
    ::dup2(devnull, 0);
    ::dup2(fds[1], 1);
    ::dup2(devnull, 2);
    ::close_range(3, ~0U, 0);
    ::execvp(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  std::string text;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  bool timed_out = false;
  char buf[8192];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline -
                                                                            std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      timed_out = true;
      ::kill(pid, SIGKILL);
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int n = ::poll(&p, 1, static_cast<int>(left.count()));
    if (n <= 0) continue;
    const ssize_t got = ::read(fds[0], buf, sizeof buf);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    if (text.size() < (8u << 20)) text.append(buf, static_cast<std::size_t>(got));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) {
    why = rackd + " --list-classes --json did not finish in " + std::to_string(timeout_ms) + " ms";
    return false;
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    why = WIFEXITED(status) && WEXITSTATUS(status) == 127 ? "cannot run " + rackd
                                                          : rackd + " --list-classes --json failed";
    return false;
  }
  if (!parse_class_list(text, out, why)) {
    why = rackd + " --list-classes --json: " + why;
    return false;
  }
  return true;
}

}  // namespace rack::tools
