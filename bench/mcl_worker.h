// The MCL filter's second likelihood thread for the benchmarks (MclOptions::threads 2):
// a rack::ComputeWorker served by a thread of the benchmark, as rackd's executor serves
// the MCL component's (Component::add_compute_worker) with the data task's priority and
// CPUs. Here the benchmark's own thread, normal scheduling, any CPU: what rackd gives
// MCL's priority-0 data task in configs/sim_mcl.yaml.
#pragma once

#include <thread>

#include "rack/core/compute_worker.h"

namespace rack::bench {

class ServedComputeWorker {
 public:
  ServedComputeWorker() : thread_([this] { worker_.serve(); }) {}
  ~ServedComputeWorker() {
    worker_.stop();
    thread_.join();
  }
  ServedComputeWorker(const ServedComputeWorker&) = delete;
  ServedComputeWorker& operator=(const ServedComputeWorker&) = delete;
  [[nodiscard]] ComputeWorker* get() noexcept { return &worker_; }

 private:
  ComputeWorker worker_;
  std::thread thread_;
};

// One for the whole run (made at first use).
inline ComputeWorker* mcl_compute_worker() {
  static ServedComputeWorker served;
  return served.get();
}

}  // namespace rack::bench
