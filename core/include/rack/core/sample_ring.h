// A data component's preallocated ring of timestamped samples.
//
// Lookup rules (RACK's getData): time 0 gives the newest sample; otherwise the
// sample nearest in time; a time older than the oldest sample, or newer than the
// newest plus `max_ahead_ns` (two periods), is an error.
//
// Thread-safety: one writer (the data task); any number of readers (command task,
// tools). Each slot is a seqlock: the writer makes the slot's sequence odd, writes,
// then publishes it even; a reader copies and re-checks the sequence. Words are
// accessed through atomic_ref, so concurrent access is well-defined.
// Real-time contract: write() and read() are RT-safe and lock-free; the writer never
// waits; a reader retries a bounded number of times.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>

#include "rack/core/wire.h"

namespace rack {

enum class RingLookup : uint8_t {
  kOk,
  kEmpty,      // nothing written yet
  kTooOld,     // before the oldest sample still held
  kTooNew,     // after newest + max_ahead
  kContended,  // the writer overtook the reader repeatedly (ring too small for the rate)
};
[[nodiscard]] const char* describe(RingLookup r) noexcept;

class SampleRing {
 public:
  // Not RT-safe (allocates). `payload_size` is the sample's size without its header.
  SampleRing(uint32_t capacity, uint32_t payload_size);

  [[nodiscard]] uint32_t capacity() const noexcept { return capacity_; }
  [[nodiscard]] uint32_t payload_size() const noexcept { return payload_size_; }
  [[nodiscard]] uint64_t written() const noexcept { return head_.load(std::memory_order_acquire); }

  // Writer only. Returns the sample's sequence number. RT-safe.
  uint64_t write(int64_t time_ns, const void* payload) noexcept;

  // Reader: the sample for `time_ns` by the lookup rules. RT-safe.
  RingLookup read(int64_t time_ns, int64_t max_ahead_ns, wire::SampleHeader& header, void* payload) const noexcept;
  // Reader: sample number `sequence` if still held. RT-safe.
  bool read_sequence(uint64_t sequence, wire::SampleHeader& header, void* payload) const noexcept;

 private:
  static constexpr uint32_t kHeaderWords = 3;  // seq, time, sequence
  uint64_t* slot(uint64_t sequence) const noexcept { return words_.get() + (sequence % capacity_) * slot_words_; }
  bool read_time(uint64_t sequence, int64_t& time) const noexcept;

  uint32_t capacity_;
  uint32_t payload_size_;
  uint32_t slot_words_;
  std::unique_ptr<uint64_t[]> words_;
  // Count of samples written. release on store so a reader that sees it sees the
  // slot's published sequence too.
  std::atomic<uint64_t> head_{0};
};

}  // namespace rack
