// rack-gui's reports: the mode-switch and crash report files (rackd-*.report) of the
// hosts on this machine, symbolized with rack-backtrace (a separate process, so libdw's
// work never delays the robots' state) on a thread of its own, as reports are added.
//
// Every 2 s: the reports added to a file since the last look are symbolized, and only
// those (rackd appends; a file of 1830 reports took 32 s to symbolize again whenever
// one was added). The new part goes to rack-backtrace with the file's header and
// module lines and the old reports blanked out, so its "file:line" references stay
// those of the real file. A report still being written (no `end` line yet) waits for
// the next look; one that stays incomplete for a whole look is passed on as it is
// (rack-backtrace then says it is truncated). Each file keeps its newest
// kMaxReportText bytes of text. stop() kills a rack-backtrace still running, so
// rack-gui exits promptly.
//
// Not RT code (a tool). Thread-safety: start() and stop() from one thread; snapshot()
// from any thread; `publish` is called from the watcher's thread.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

namespace rack::gui {

class ReportWatcher {
 public:
  // A {"type":"reports","dir":..,"reports":[{"file":..,"text":..}]} message for every browser.
  using Publish = std::function<void(std::string message)>;
  static constexpr std::size_t kMaxReportText = 256 * 1024;  // per file: the newest reports

  // `dir`: where the report files are; `backtrace_path`: rack-backtrace ("" = beside
  // rack-gui, else on PATH).
  ReportWatcher(std::string dir, std::string backtrace_path, Publish publish);
  ~ReportWatcher();
  ReportWatcher(const ReportWatcher&) = delete;
  ReportWatcher& operator=(const ReportWatcher&) = delete;

  void start();
  void stop();
  // The "reports" message of what was symbolized so far, for a browser that just
  // connected ("" when there is nothing).
  [[nodiscard]] std::string snapshot() const;

 private:
  struct FileState {
    std::uintmax_t size = 0;
    std::filesystem::file_time_type mtime;
    std::size_t done = 0;    // bytes symbolized so far (whole lines)
    bool tail_seen = false;  // an incomplete tail was there at the last look
  };
  void run();
  std::string symbolize_new(const std::string& file, FileState& st, bool flush_tail);
  [[nodiscard]] std::string backtrace_program() const;
  [[nodiscard]] std::string symbolize(const std::string& file) const;
  [[nodiscard]] std::string message_locked() const;

  const std::string dir_;
  const std::string backtrace_path_;
  const Publish publish_;
  std::atomic<bool> running_{false};
  std::thread thread_;
  mutable std::mutex mutex_;                  // texts_: the watcher's thread -> snapshot()
  std::map<std::string, std::string> texts_;  // report file -> rack-backtrace's output
};

}  // namespace rack::gui
