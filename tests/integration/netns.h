// Several "hosts" on one machine: one network namespace per host, each with a veth
// link to a bridge that lives in a switch namespace of its own (so nothing of the
// machine's own network changes). Multicast snooping is off on the bridge, so LCM's
// multicast reaches every host as on a plain switch.
//
// Names are unique per test run (rkit-<pid>-<n>-...). The destructor deletes every
// namespace it made; a run that died before its destructor (watchdog, crash) leaves
// namespaces whose pid no longer exists, and the next NetnsTopology deletes those.
#pragma once

#include <optional>
#include <string>
#include <vector>

namespace rack::test {

class NetnsTopology {
 public:
  // Why multi-host tests cannot run here (not root, no `ip`, namespaces refused), or
  // nullopt when they can.
  static std::optional<std::string> unsupported_reason();

  // Creates `hosts` host namespaces on one bridge. Throws std::runtime_error naming
  // the failed command (what was made is deleted again).
  explicit NetnsTopology(int hosts);
  ~NetnsTopology();
  NetnsTopology(const NetnsTopology&) = delete;
  NetnsTopology& operator=(const NetnsTopology&) = delete;

  [[nodiscard]] const std::string& host(int i) const { return hosts_.at(static_cast<std::size_t>(i)); }
  [[nodiscard]] int size() const { return static_cast<int>(hosts_.size()); }
  // Takes host i's cable out (the bridge end of its veth goes down) or puts it back.
  // The host keeps its address and routes, as with a pulled cable.
  void set_link(int i, bool up);

 private:
  void ip(const std::vector<std::string>& args);
  std::string prefix_;
  std::string switch_;
  std::vector<std::string> hosts_;
  std::vector<std::string> made_;  // namespaces to delete
};

}  // namespace rack::test
