// GET_TASKS' reply (TASKS): how a component runs now, so that a tool draws the
// deployment as it runs from discovery alone (issue 25: `rackctl graph --live`,
// `rackctl alloc --live` with no host file). Per task (index 0 the command task, 1 the
// data task): the priority and CPU the host file asked for, and what the kernel says
// of the thread (its policy and priority, the CPUs it may run on and the one it ran
// on last, read by the executor's non-RT thread once a second: rack/rt/task_sched.h),
// the data task's timer period and the mean interval between its loop() runs over
// the last second; and the TiMS networks its host joined (name, URL, scope), so that
// a tool can say which networks a flow between two hosts crosses.
//
// Versioned: `version` is the first byte. Version 1 is exactly sizeof(TasksReply). A
// later version may only append fields: a client takes the version-1 part of a longer
// body whose version is above 1, and refuses version 0 or a body shorter than
// version 1. decode_tasks() is the client's check (the fuzz harness' entry:
// tests/fuzz/fuzz_tasks.cpp).
//
// A framework type (core/, not a class's data type). Real-time contract: plain data;
// everything here is RT-safe.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

#include "rack/core/wire.h"
#include "rack/tims/payload.h"

namespace rack::wire {

inline constexpr uint8_t kTasksVersion = 1;
inline constexpr std::size_t kTaskRecords = 2;          // the command task, the data task
inline constexpr std::size_t kTaskCpuWords = 4;         // affinity: CPUs 0..255
inline constexpr std::size_t kMaxTaskNetworks = 4;      // networks of the host listed
inline constexpr std::size_t kTaskNetworkNameLen = 32;  // per network, NUL-terminated
inline constexpr std::size_t kTaskNetworkUrlLen = 96;   // per network, NUL-terminated (cut)
inline constexpr uint8_t kTaskMeasured = 1;             // TasksReply::measured: read from the kernel

struct TasksReply {
  uint8_t version = kTasksVersion;
  uint8_t data_task = 0;      // as StatsReply: 0 none, 1 periodic, 2 triggered
  uint8_t task_count = 0;     // records in use: 1 (command task) or 2 (and the data task)
  uint8_t network_count = 0;  // 0..kMaxTaskNetworks
  uint32_t online_cpus = 0;   // CPUs online on the host (0: not measured yet)
  // Per task i < task_count.
  uint8_t measured[kTaskRecords] = {};  // kTaskMeasured: the fields below "as it runs" are the kernel's
  uint8_t policy[kTaskRecords] = {};    // as it runs: SCHED_OTHER 0, FIFO 1, RR 2, BATCH 3, IDLE 5, DEADLINE 6
  uint8_t reserved[4] = {};
  int32_t priority[kTaskRecords] = {};             // as it runs: 1..99 under FIFO/RR, else 0
  int32_t last_cpu[kTaskRecords] = {};             // as it runs: the CPU it ran on last (-1: not measured)
  int32_t configured_priority[kTaskRecords] = {};  // the host file's (0..99)
  int32_t configured_cpu[kTaskRecords] = {};       // the host file's cpu (-1: not pinned)
  // As it runs: bit c % 64 of affinity[i * kTaskCpuWords + c / 64]: task i may run on CPU c.
  uint64_t affinity[kTaskRecords * kTaskCpuWords] = {};
  int64_t period_ns[kTaskRecords] = {};           // the timer's period (periodic data task), else 0
  int64_t measured_period_ns[kTaskRecords] = {};  // mean interval between loop() runs lately (0: unknown)
  int64_t sampled_ago_ns[kTaskRecords] = {};      // age of the kernel reading (measured only)
  // The host's TiMS networks, j < network_count: name and URL in fixed slots of
  // kTaskNetworkNameLen and kTaskNetworkUrlLen bytes, scope 0 robot, 1 fleet.
  uint8_t network_scope[kMaxTaskNetworks] = {};
  uint8_t reserved2[4] = {};
  char network_name[kMaxTaskNetworks * kTaskNetworkNameLen] = {};
  char network_url[kMaxTaskNetworks * kTaskNetworkUrlLen] = {};
  static constexpr auto fields() noexcept {
    return std::array{RACK_FIELD(TasksReply, version),        RACK_FIELD(TasksReply, data_task),
                      RACK_FIELD(TasksReply, task_count),     RACK_FIELD(TasksReply, network_count),
                      RACK_FIELD(TasksReply, online_cpus),    RACK_FIELD(TasksReply, measured),
                      RACK_FIELD(TasksReply, policy),         RACK_FIELD(TasksReply, priority),
                      RACK_FIELD(TasksReply, last_cpu),       RACK_FIELD(TasksReply, configured_priority),
                      RACK_FIELD(TasksReply, configured_cpu), RACK_FIELD(TasksReply, affinity),
                      RACK_FIELD(TasksReply, period_ns),      RACK_FIELD(TasksReply, measured_period_ns),
                      RACK_FIELD(TasksReply, sampled_ago_ns), RACK_FIELD(TasksReply, network_scope),
                      RACK_FIELD(TasksReply, network_name),   RACK_FIELD(TasksReply, network_url)};
  }
  // Network j's name and URL (j < kMaxTaskNetworks). RT-safe.
  [[nodiscard]] const char* name_of_network(std::size_t j) const noexcept {
    return network_name + j * kTaskNetworkNameLen;
  }
  [[nodiscard]] const char* url_of_network(std::size_t j) const noexcept {
    return network_url + j * kTaskNetworkUrlLen;
  }
};
static_assert(sizeof(TasksReply) == 680, "TASKS version 1: a fixed layout on the wire");

namespace detail {
// A NUL within the slot, and nothing but printable ASCII before it.
[[nodiscard]] inline bool slot_text_ok(const char* s, std::size_t len, bool may_be_empty) noexcept {
  for (std::size_t i = 0; i < len; ++i) {
    if (s[i] == '\0') return i > 0 || may_be_empty;
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c > 0x7e) return false;
  }
  return false;
}
}  // namespace detail

// What is wrong with a TASKS reply a client received, or nullptr when it is usable.
// Only the records and networks in use are checked. RT-safe.
[[nodiscard]] inline const char* check_tasks_reply(const TasksReply& r) noexcept {
  if (r.version == 0) return "version is 0";
  if (r.data_task > 2) return "data_task is not 0..2";
  if (r.task_count != (r.data_task == 0 ? 1 : 2)) return "task_count is not 1 without a data task, 2 with one";
  if (r.network_count > kMaxTaskNetworks) return "network_count is above 4";
  if (r.online_cpus > 4096) return "online_cpus is above 4096";
  for (std::size_t i = 0; i < r.task_count; ++i) {
    if (r.configured_priority[i] < 0 || r.configured_priority[i] > 99) return "a configured priority is not 0..99";
    if (r.configured_cpu[i] < -1 || r.configured_cpu[i] > 4095) return "a configured cpu is not -1..4095";
    if (r.period_ns[i] < 0 || r.measured_period_ns[i] < 0) return "a period is negative";
    if (i == 0 && r.period_ns[0] != 0) return "the command task has a period";
    if (r.measured[i] > kTaskMeasured) return "measured is not 0 or 1";
    if (r.measured[i] == 0) continue;
    const uint8_t p = r.policy[i];
    if (p != 0 && p != 1 && p != 2 && p != 3 && p != 5 && p != 6) return "a policy is not a scheduling policy";
    if (r.priority[i] < 0 || r.priority[i] > 99) return "a priority is not 0..99";
    if ((r.priority[i] > 0) != (p == 1 || p == 2)) return "a priority does not go with its policy";
    if (r.last_cpu[i] < 0 || r.last_cpu[i] > 4095) return "a last cpu is not 0..4095";
    if (r.sampled_ago_ns[i] < 0) return "a reading's age is negative";
    uint64_t any = 0;
    for (std::size_t w = 0; w < kTaskCpuWords; ++w) any |= r.affinity[i * kTaskCpuWords + w];
    if (any == 0) return "a task may run on no CPU";
  }
  for (std::size_t j = 0; j < r.network_count; ++j) {
    if (r.network_scope[j] > 1) return "a network's scope is not 0 (robot) or 1 (fleet)";
    if (!detail::slot_text_ok(r.name_of_network(j), kTaskNetworkNameLen, false)) {
      return "a network's name is empty, unterminated or not printable";
    }
    if (!detail::slot_text_ok(r.url_of_network(j), kTaskNetworkUrlLen, true)) {
      return "a network's URL is unterminated or not printable";
    }
  }
  return nullptr;
}

// Decodes a TASKS body: nullptr with `out` filled (the version-1 part), else what is
// wrong (the size for its version, or check_tasks_reply's answer). RT-safe.
[[nodiscard]] inline const char* decode_tasks(std::span<const std::byte> body, bool native, TasksReply& out) noexcept {
  if (body.size() < sizeof(TasksReply)) return "the body is shorter than a TASKS reply (680 bytes)";
  const auto version = static_cast<uint8_t>(body[0]);
  if (version == 0) return "version is 0";
  if (version == 1 && body.size() != sizeof(TasksReply)) return "a version-1 TASKS reply is 680 bytes";
  std::memcpy(&out, body.data(), sizeof(TasksReply));
  if (!native) tims::swap_fields(tims::fields_of<TasksReply>, reinterpret_cast<std::byte*>(&out), sizeof(TasksReply));
  return check_tasks_reply(out);
}

}  // namespace rack::wire
