#include "config_service.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <optional>

#include <nlohmann/json.hpp>

#include "rack/client/deployment.h"
#include "rack/client/host_file.h"
#include "class_info.h"

namespace rack::gui {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

constexpr std::size_t kMaxOutput = 4u << 20;  // bytes of a child's output kept

struct ChildResult {
  int exit_code = -1;  // -1: killed (timeout) or not started; 127: exec failed
  bool timed_out = false;
  std::string out;
};

// Runs `args` with `cwd`, stdout (and stderr when `merge`) captured, killed after
// `timeout_ms`. Every other descriptor of rack-gui is closed in the child.
ChildResult run_child(const std::vector<std::string>& args, const std::string& cwd, bool merge, int timeout_ms) {
  ChildResult r;
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    r.out = std::string("pipe: ") + std::strerror(errno);
    return r;
  }
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fds[0]);
    ::close(fds[1]);
    r.out = std::string("fork: ") + std::strerror(errno);
    return r;
  }
  if (pid == 0) {  // the child: async-signal-safe calls only, then exec
    const int devnull = ::open("/dev/null", O_RDWR);
    ::dup2(devnull, 0);
    ::dup2(fds[1], 1);
    ::dup2(merge ? fds[1] : devnull, 2);
    ::close_range(3, ~0U, 0);
    if (!cwd.empty() && ::chdir(cwd.c_str()) != 0) ::_exit(126);
    ::execvp(argv[0], argv.data());
    ::_exit(127);
  }
  ::close(fds[1]);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(timeout_ms);
  char buf[8192];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline -
                                                                            std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      r.timed_out = true;
      ::kill(pid, SIGKILL);
      break;
    }
    pollfd p{fds[0], POLLIN, 0};
    const int n = ::poll(&p, 1, static_cast<int>(left.count()));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) continue;
    const ssize_t got = ::read(fds[0], buf, sizeof buf);
    if (got < 0 && errno == EINTR) continue;
    if (got <= 0) break;
    if (r.out.size() < kMaxOutput) r.out.append(buf, static_cast<std::size_t>(got));
  }
  ::close(fds[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!r.timed_out && WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
  return r;
}

bool valid_name(const std::string& n) {
  if (n.empty() || n.size() > 255 || n[0] == '.') return false;
  for (const char c : n) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '.' || c == '_' || c == '-')) return false;
  }
  const auto ends = [&](const char* s) {
    const std::size_t l = std::strlen(s);
    return n.size() > l && n.compare(n.size() - l, l, s) == 0;
  };
  return ends(".yaml") || ends(".yml");
}

json reply(const json& request, const std::string& op) {
  json r = {{"type", "config"}, {"op", op}};
  if (request.is_object() && request.contains("id") && request["id"].is_number_integer()) r["id"] = request["id"];
  return r;
}

// rackd --check's complaints about `checked` (the temporary file), as the editor shows
// them: line, column (0: the whole file) and message.
// What identifies the file on disk as the client saw it (config_load, a save): its
// modification time in ns, size and inode; "" when it does not exist. A save whose
// base_version differs was made against a text that is no longer on disk.
std::string disk_version(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return "";
  return std::to_string(static_cast<long long>(st.st_mtim.tv_sec)) + "." + std::to_string(st.st_mtim.tv_nsec) + ":" +
         std::to_string(static_cast<long long>(st.st_size)) + ":" + std::to_string(st.st_ino);
}

json check_errors(const std::string& output, const std::string& checked, const std::string& shown) {
  json errors = json::array();
  std::size_t at = 0;
  while (at < output.size()) {
    const std::size_t end = std::min(output.find('\n', at), output.size());
    std::string line = output.substr(at, end - at);
    at = end + 1;
    if (line.rfind(checked + ":", 0) != 0) continue;
    std::string rest = line.substr(checked.size() + 1);
    int ln = 0;
    int col = 0;
    const std::size_t c1 = rest.find(':');
    const std::size_t c2 = c1 == std::string::npos ? std::string::npos : rest.find(':', c1 + 1);
    if (c2 != std::string::npos) {
      const std::string line_text = rest.substr(0, c1);
      const std::string column_text = rest.substr(c1 + 1, c2 - c1 - 1);
      char* e1 = nullptr;
      char* e2 = nullptr;
      const long l = std::strtol(line_text.c_str(), &e1, 10);
      const long c = std::strtol(column_text.c_str(), &e2, 10);
      if (*e1 == '\0' && *e2 == '\0' && c1 > 0 && c2 > c1 + 1 && l > 0 && c > 0) {
        ln = static_cast<int>(l);
        col = static_cast<int>(c);
        rest = rest.substr(c2 + 1);
      }
    }
    if (!rest.empty() && rest[0] == ' ') rest.erase(0, 1);
    // The temporary file's name never reaches the browser: the file's does.
    for (std::size_t p = rest.find(checked); p != std::string::npos; p = rest.find(checked, p + shown.size())) {
      rest.replace(p, checked.size(), shown);
    }
    errors.push_back({{"line", ln}, {"column", col}, {"message", rest}});
  }
  return errors;
}

}  // namespace

ConfigService::ConfigService(ConfigServiceConfig config, Sink sink)
    : config_(std::move(config)), sink_(std::move(sink)) {
  for (auto& d : config_.dirs) {
    std::error_code ec;
    const fs::path canonical = fs::weakly_canonical(fs::absolute(d, ec), ec);
    if (!ec) d = canonical.string();
  }
  thread_ = std::thread([this] { run(); });
}

ConfigService::~ConfigService() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool ConfigService::handles(std::string_view text) noexcept {
  try {
    const json j = json::parse(text, nullptr, false);
    if (!j.is_object()) return false;
    const auto it = j.find("op");
    return it != j.end() && it->is_string() && it->get_ref<const std::string&>().rfind("config_", 0) == 0;
  } catch (...) {
    return false;
  }
}

void ConfigService::submit(uint64_t client, std::string text) {
  {
    const std::lock_guard lock(mutex_);
    if (queue_.size() < kMaxQueued) {
      queue_.emplace_back(client, std::move(text));
      wake_.notify_one();
      return;
    }
  }
  sink_(client, json({{"type", "config"},
                      {"ok", false},
                      {"error", "busy: " + std::to_string(kMaxQueued) + " configuration requests wait already"}})
                    .dump());
}

void ConfigService::run() {
  pthread_setname_np(pthread_self(), "gui:config");
  for (;;) {
    std::pair<uint64_t, std::string> item;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (stop_) return;
      item = std::move(queue_.front());
      queue_.pop_front();
    }
    std::string out = handle(item.second);
    sink_(item.first, std::move(out));
  }
}

std::string ConfigService::rackd_program() const {
  if (!config_.rackd_path.empty()) return config_.rackd_path;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec).parent_path();
  if (!ec) {
    // Installed: beside rack-gui; in a build tree: tools/rackd next to tools/gui/.
    for (const auto& candidate : {self / "rackd", self.parent_path() / "rackd"}) {
      if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
  }
  return "rackd";  // on PATH
}

std::string ConfigService::rackctl_program() const {
  if (!config_.rackctl_path.empty()) return config_.rackctl_path;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec).parent_path();
  if (!ec) {
    for (const auto& candidate : {self / "rackctl", self.parent_path() / "rackctl"}) {
      if (::access(candidate.c_str(), X_OK) == 0) return candidate.string();
    }
  }
  return "rackctl";  // on PATH
}

std::string ConfigService::served_file(const std::string& file, std::string& why) const {
  const fs::path p(file);
  const std::string name = p.filename().string();
  if (!p.is_absolute()) {
    why = "'" + file + "' is not a path config_files listed (absolute)";
    return "";
  }
  if (!valid_name(name)) {
    why = "'" + name + "' is not a host file name (letters, digits, '.', '_', '-'; *.yaml or *.yml; no leading '.')";
    return "";
  }
  std::error_code ec;
  const fs::path dir = fs::weakly_canonical(p.parent_path(), ec);
  bool served = false;
  for (const auto& d : config_.dirs) served = served || (!ec && dir.string() == d);
  if (!served) {
    why = "'" + file + "' is not in a directory rack-gui serves (--config)";
    return "";
  }
  const fs::path full = dir / name;
  struct stat st {};
  if (::lstat(full.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
    why = full.string();
    why.insert(0, 1, '\'');
    why += "' is not a regular file (symbolic links are not followed)";
    return "";
  }
  return full.string();
}

std::string ConfigService::handle(std::string_view text) {
  json request = json::parse(text, nullptr, false);
  json r = reply(request, request.is_object() && request.contains("op") && request["op"].is_string()
                              ? request["op"].get<std::string>()
                              : std::string("?"));
  const auto refuse = [&](const std::string& why) {
    r["ok"] = false;
    r["error"] = why;
    return r.dump(-1, ' ', false, json::error_handler_t::replace);
  };
  if (!request.is_object()) return refuse("a configuration request is a JSON object with \"op\"");
  const std::string op = r["op"].get<std::string>();
  const auto text_of = [&](const char* key, std::string& out) {
    const auto it = request.find(key);
    if (it == request.end() || !it->is_string()) return false;
    out = it->get<std::string>();
    return true;
  };
  try {
    if (op == "config_files") {
      json dirs = json::array();
      for (const auto& d : config_.dirs) {
        std::vector<std::string> problems;
        json files = json::array();
        for (const auto& path : rack::deploy::host_file_paths({d}, problems)) {
          const std::string name = fs::path(path).filename().string();
          if (valid_name(name)) files.push_back({{"name", name}, {"file", (fs::path(d) / name).string()}});
        }
        dirs.push_back({{"dir", d}, {"files", files}, {"problems", problems}});
      }
      r["ok"] = true;
      r["dirs"] = dirs;
    } else if (op == "config_graph") {
      std::string dir;
      const auto live = request.find("live");
      const bool want_live = live != request.end() && live->is_boolean() && live->get<bool>();
      // Without "dir", live: the deployment as it runs, from discovery alone.
      const bool discovery = request.find("dir") == request.end() && want_live;
      if (!discovery && !text_of("dir", dir)) {
        return refuse(
            "config_graph needs \"dir\": a directory config_files listed (or only \"live\": true: what runs)");
      }
      bool served = discovery;
      for (const auto& d : config_.dirs) served = served || d == dir;
      if (!served) return refuse("'" + dir + "' is not a directory rack-gui serves (--config)");
      std::vector<std::string> problems, paths;
      std::vector<rack::deploy::Host> hosts;
      for (const auto& path : discovery ? std::vector<std::string>{} : rack::deploy::host_file_paths({dir}, problems)) {
        if (!valid_name(fs::path(path).filename().string())) continue;
        hosts.push_back(rack::deploy::read_host(path));
        paths.push_back(path);
      }
      // The classes' component references (rackd --list-classes --json with the
      // directory's host files: their plug-in classes too), learnt once per directory.
      auto known = class_info_.find(dir);
      if (!discovery && known == class_info_.end()) {
        std::vector<rack::deploy::ClassInfo> classes;
        std::string why;
        if (rack::tools::classes_from_rackd(rackd_program(), classes, why, config_.timeout_ms, paths)) {
          known = class_info_.emplace(dir, std::move(classes)).first;
        } else {
          r["classes_error"] = why + ": every parameter naming a component is taken for a flow";
        }
      }
      const rack::deploy::Deployment d = rack::deploy::build(std::move(hosts),
                                                             known != class_info_.end() ? &known->second : nullptr);
      std::string dot = rack::deploy::to_dot(d);
      r["ok"] = true;
      r["deployment"] = json::parse(rack::deploy::to_json(d), nullptr, false);
      r["allocation"] = rack::deploy::allocation_text(d);
      if (want_live) {
        // What the network says, by rackctl on rack-gui's network (two discoveries).
        std::vector<std::string> base{rackctl_program(), "--lcm", config_.lcm_url, "--discover-ms", "500",
                                      "--timeout",       "500"};
        if (!config_.key_file.empty()) base.insert(base.end(), {"--key-file", config_.key_file});
        auto with = [&](std::vector<std::string> tail) {
          std::vector<std::string> args = base;
          args.insert(args.end(), tail.begin(), tail.end());
          if (!discovery) args.push_back(dir);
          return args;
        };
        const ChildResult g = run_child(with({"graph", "--live", "--format", "json", "--rackd", rackd_program()}), "",
                                        false, config_.timeout_ms);
        const ChildResult dd = run_child(with({"graph", "--live", "--rackd", rackd_program()}), "", false,
                                         config_.timeout_ms);
        const ChildResult a = run_child(with({"alloc", "--live", "--rackd", rackd_program()}), "", false,
                                        config_.timeout_ms);
        json lj = json::parse(g.out, nullptr, false);
        // Exit 1 is a host file with errors: the picture is still made.
        if ((g.exit_code == 0 || g.exit_code == 1) && lj.is_object() && (dd.exit_code == 0 || dd.exit_code == 1) &&
            (a.exit_code == 0 || a.exit_code == 1)) {
          r["deployment"] = lj;
          dot = dd.out;
          r["allocation"] = a.out;
          r["live"] = true;
        } else {
          r["live"] = false;
          r["live_error"] = discovery && g.exit_code == 3
                                ? std::string("no host answered discovery on ") + config_.lcm_url
                                : "rackctl --live failed (exit " + std::to_string(g.exit_code) +
                                      "): " + g.out.substr(0, 512);
        }
      }
      r["dot"] = dot;
      r["problems"] = problems;
      // SVG through graphviz (a temporary DOT file: dot reads it, its SVG is captured).
      char tmp[] = "/tmp/rack-gui-graph-XXXXXX";
      const int fd = ::mkstemp(tmp);
      if (fd >= 0) {
        const bool written = ::write(fd, dot.data(), dot.size()) == static_cast<ssize_t>(dot.size());
        ::close(fd);
        const ChildResult svg = written ? run_child({config_.dot_path, "-Tsvg", tmp}, "", false, config_.timeout_ms)
                                        : ChildResult{};
        ::unlink(tmp);
        if (svg.exit_code == 0) r["svg"] = svg.out;
        else if (svg.exit_code == 127) r["svg_error"] = "graphviz's dot is not installed (apt-get install graphviz)";
        else r["svg_error"] = "dot failed: " + svg.out.substr(0, 512);
      }
    } else if (op == "config_classes") {
      // With every served host file: the plug-in classes they name are described too.
      std::vector<std::string> args{rackd_program(), "--list-classes", "--json"};
      for (const auto& d : config_.dirs) {
        std::vector<std::string> problems;
        for (const auto& path : rack::deploy::host_file_paths({d}, problems)) {
          if (valid_name(fs::path(path).filename().string())) args.push_back(path);
        }
      }
      const ChildResult c = run_child(args, "", false, config_.timeout_ms);
      json classes = json::parse(c.out, nullptr, false);
      if (c.exit_code != 0 || !classes.is_array()) {
        return refuse("'" + rackd_program() + " --list-classes --json' failed (exit " + std::to_string(c.exit_code) +
                      ")");
      }
      r["ok"] = true;
      r["classes"] = classes;
    } else if (op == "config_load") {
      std::string file, why;
      if (!text_of("file", file)) return refuse("config_load needs \"file\"");
      const std::string path = served_file(file, why);
      if (path.empty()) return refuse(why);
      const auto bytes = rack::read_host_bytes(path, why);
      if (!bytes) return refuse(path + ": " + why);
      r["ok"] = true;
      r["file"] = path;
      r["text"] = *bytes;
      r["disk_version"] = disk_version(path);
    } else if (op == "config_part") {
      // A text above one WebSocket message, in parts (config_service.h: uploads).
      std::string upload, part;
      const auto index = request.find("index");
      const auto count = request.find("count");
      if (!text_of("upload", upload) || !text_of("text", part) || index == request.end() ||
          !index->is_number_unsigned() || count == request.end() || !count->is_number_unsigned()) {
        return refuse("config_part needs \"upload\", \"index\", \"count\" and \"text\"");
      }
      if (upload.empty() || upload.size() > 32 || !std::all_of(upload.begin(), upload.end(), [](char c) {
            return std::isalnum(static_cast<unsigned char>(c));
          })) {
        return refuse("config_part: \"upload\" is 1..32 letters or digits");
      }
      const auto i = index->get<uint64_t>();
      const auto n = count->get<uint64_t>();
      if (n == 0 || n > kMaxUploadParts) {
        return refuse("config_part: \"count\" is 1.." + std::to_string(kMaxUploadParts));
      }
      auto it = uploads_.find(upload);
      if (i == 0) {
        if (it != uploads_.end()) uploads_.erase(it);
        while (uploads_.size() >= kMaxUploads) {  // the oldest gives way
          auto oldest = uploads_.begin();
          for (auto u = uploads_.begin(); u != uploads_.end(); ++u) {
            if (u->second.started < oldest->second.started) oldest = u;
          }
          uploads_.erase(oldest);
        }
        it = uploads_.emplace(upload, Upload{}).first;
        it->second.count = n;
        it->second.started = std::chrono::steady_clock::now();
      } else if (it == uploads_.end()) {
        return refuse("config_part: upload '" + upload + "' has no part 0 (or was dropped: at most " +
                      std::to_string(kMaxUploads) + " at once)");
      }
      Upload& u = it->second;
      if (n != u.count || i != u.received) {
        const std::string why_not = "config_part: upload '" + upload + "': part " + std::to_string(i) + " of " +
                                    std::to_string(n) + " out of order (expected part " + std::to_string(u.received) +
                                    " of " + std::to_string(u.count) + "); the upload is dropped";
        uploads_.erase(it);
        return refuse(why_not);
      }
      if (u.text.size() + part.size() > rack::kMaxHostFileBytes) {
        uploads_.erase(it);
        return refuse("config_part: upload '" + upload + "' is larger than a host file may be (" +
                      std::to_string(rack::kMaxHostFileBytes) + " bytes); the upload is dropped");
      }
      u.text += part;
      ++u.received;
      r["ok"] = true;
      r["upload"] = upload;
      r["received"] = u.received;
      r["count"] = u.count;
    } else if (op == "config_check" || op == "config_save") {
      std::string file, body, why, upload;
      if (text_of("upload", upload)) {
        // The text sent in parts (config_part): complete, then used once.
        const auto it = uploads_.find(upload);
        if (it == uploads_.end()) return refuse(op + ": no upload '" + upload + "' (config_part first)");
        if (it->second.received != it->second.count) {
          const std::string got = std::to_string(it->second.received) + " of " + std::to_string(it->second.count);
          uploads_.erase(it);
          return refuse(op + ": upload '" + upload + "' is incomplete (" + got + " parts); the upload is dropped");
        }
        body = std::move(it->second.text);
        uploads_.erase(it);
        if (!text_of("file", file)) return refuse(op + " needs \"file\"");
      } else if (!text_of("file", file) || !text_of("text", body)) {
        return refuse(op + " needs \"file\" and \"text\" (or \"upload\", sent with config_part)");
      }
      const std::string path = served_file(file, why);
      if (path.empty()) return refuse(why);
      if (body.size() > rack::kMaxHostFileBytes) return refuse("the text is larger than a host file may be");
      // The text in a temporary file beside the file: relative paths resolve as for it.
      const fs::path dir = fs::path(path).parent_path();
      std::string tmp = (dir / ("." + fs::path(path).filename().string() + ".rack-gui-XXXXXX.yaml")).string();
      const int fd = ::mkstemps(tmp.data(), 5);
      if (fd < 0) return refuse("cannot write beside " + path + ": " + std::strerror(errno));
      bool keep = false;
      struct Unlink {
        const std::string& f;
        bool& keep;
        ~Unlink() {
          if (!keep) ::unlink(f.c_str());
        }
      } unlink_tmp{tmp, keep};
      std::size_t done = 0;
      while (done < body.size()) {
        const ssize_t n = ::write(fd, body.data() + done, body.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        done += static_cast<std::size_t>(n);
      }
      struct stat old {};
      if (::stat(path.c_str(), &old) == 0) (void)::fchmod(fd, old.st_mode & 07777);
      else (void)::fchmod(fd, 0644);
      const bool synced = ::fsync(fd) == 0;
      ::close(fd);
      if (done != body.size() || !synced) return refuse("cannot write beside " + path + ": " + std::strerror(errno));
      const ChildResult c = run_child({rackd_program(), "--check", tmp}, dir.string(), true, config_.timeout_ms);
      r["valid"] = c.exit_code == 0;
      r["errors"] = check_errors(c.out, tmp, path);
      r["file"] = path;
      if (c.exit_code != 0 && r["errors"].empty()) {
        r["errors"].push_back({{"line", 0},
                               {"column", 0},
                               {"message", c.timed_out          ? "rackd --check did not finish in time"
                                           : c.exit_code == 127 ? "cannot run " + rackd_program()
                                                                : c.out.substr(0, 1024)}});
      }
      r["ok"] = true;
      // The file changed on disk since the client loaded it (another editor, a
      // checkout): its diff is not against the disk, and a save would lose that change.
      std::string base;
      const bool disk_changed = text_of("base_version", base) && base != disk_version(path);
      r["disk_changed"] = disk_changed;
      if (op == "config_save") {
        r["saved"] = false;
        if (disk_changed) {
          r["save_error"] = path + " changed on disk since it was loaded: not saved (load it again, or copy the text)";
        } else if (c.exit_code == 0) {
          if (::rename(tmp.c_str(), path.c_str()) != 0)
            return refuse("cannot replace " + path + ": " + std::strerror(errno));
          keep = true;
          r["saved"] = true;
          r["disk_version"] = disk_version(path);
        }
      }
    } else {
      return refuse("unknown op '" + op +
                    "' (config_files, config_graph, config_classes, config_load, config_part, config_check, "
                    "config_save)");
    }
  } catch (const std::exception& e) {
    return refuse(std::string("internal error: ") + e.what());
  }
  return r.dump(-1, ' ', false, json::error_handler_t::replace);
}

}  // namespace rack::gui
