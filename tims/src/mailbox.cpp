#include "rack/tims/mailbox.h"

#include <cstring>

#include "rack/rt/clock.h"
#include "rack/rt/trace.h"

namespace rack::tims {

namespace {
constexpr uint32_t round_up8(uint32_t n) { return (n + 7u) & ~7u; }
void bump(std::atomic<uint64_t>& c) noexcept {
  // Written under the mailbox mutex only: a plain load/store pair is enough.
  c.store(c.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
}
}  // namespace

const char* describe(SendStatus s) noexcept {
  switch (s) {
    case SendStatus::kOk: return "ok";
    case SendStatus::kOkDroppedOlder: return "ok (an older message was dropped)";
    case SendStatus::kFull: return "mailbox full";
    case SendStatus::kTooLarge: return "message larger than a mailbox slot";
    case SendStatus::kClosed: return "mailbox closed";
    case SendStatus::kNotAvailable: return "no such mailbox";
    case SendStatus::kDenied: return "refused by access control or by a data mailbox";
  }
  return "unknown";
}

Mailbox::Mailbox(Address address, uint32_t slots, uint32_t slot_size)
    : address_(address),
      slot_count_(slots == 0 ? 1 : slots),
      slot_size_(round_up8(slot_size < sizeof(MessageHeader) ? sizeof(MessageHeader) : slot_size)),
      storage_(new std::byte[std::size_t(slot_count_) * slot_size_]),
      slots_(new SlotInfo[slot_count_]) {
  // Touch the storage now (it is locked by mlockall, but fault it in before RT use).
  std::memset(storage_.get(), 0, std::size_t(slot_count_) * slot_size_);
}

Mailbox::~Mailbox() = default;

int64_t Mailbox::deadline_for(int64_t timeout_ns) const noexcept {
  if (timeout_ns < 0) return -1;
  return rt::os_monotonic_ns() + timeout_ns;  // the futex waits on the real clock (never a virtual one)
}

int Mailbox::find_next_locked() const noexcept {
  int best = -1;
  for (uint32_t i = 0; i < slot_count_; ++i) {
    const SlotInfo& s = slots_[i];
    if (s.state != SlotState::kReady) continue;
    if (best < 0 || s.priority > slots_[static_cast<std::size_t>(best)].priority ||
        (s.priority == slots_[static_cast<std::size_t>(best)].priority &&
         s.order < slots_[static_cast<std::size_t>(best)].order)) {
      best = static_cast<int>(i);
    }
  }
  return best;
}

SendStatus Mailbox::try_send(const MessageHeader& header, std::initializer_list<ConstBuffer> body) noexcept {
  return try_send(header, std::span<const ConstBuffer>(body.begin(), body.size()));
}

SendStatus Mailbox::try_send(const MessageHeader& header, std::span<const ConstBuffer> body) noexcept {
  std::size_t total = sizeof(MessageHeader);
  for (const auto& part : body) total += part.size;
  int index = -1;
  {
    rt::PiLock lock(mutex_);
    if (closed_) return SendStatus::kClosed;
    if (total > slot_size_ || total != header.length) {
      bump(too_large_);
      return SendStatus::kTooLarge;
    }
    bool dropped = false;
    for (uint32_t i = 0; i < slot_count_; ++i) {
      if (slots_[i].state == SlotState::kFree) {
        index = static_cast<int>(i);
        break;
      }
    }
    if (index < 0) {
      // Full: the victim is the oldest message of the lowest priority.
      int victim = -1;
      for (uint32_t i = 0; i < slot_count_; ++i) {
        const SlotInfo& s = slots_[i];
        if (s.state != SlotState::kReady) continue;
        if (victim < 0 || s.priority < slots_[static_cast<std::size_t>(victim)].priority ||
            (s.priority == slots_[static_cast<std::size_t>(victim)].priority &&
             s.order < slots_[static_cast<std::size_t>(victim)].order)) {
          victim = static_cast<int>(i);
        }
      }
      if (victim < 0 || slots_[static_cast<std::size_t>(victim)].priority > header.priority) {
        bump(refused_);
        return SendStatus::kFull;
      }
      index = victim;
      --ready_count_;
      bump(dropped_);
      dropped = true;
    }
    slots_[static_cast<std::size_t>(index)].state = SlotState::kWriting;
    slots_[static_cast<std::size_t>(index)].priority = header.priority;
    if (dropped) {
      // Copy outside the lock below, but remember how this send ended.
      slots_[static_cast<std::size_t>(index)].order = UINT64_MAX;  // marker until commit
    }
  }
  std::byte* dst = slot_data(index);
  std::memcpy(dst, &header, sizeof header);
  std::size_t at = sizeof header;
  for (const auto& part : body) {
    if (part.size > 0) std::memcpy(dst + at, part.data, part.size);
    at += part.size;
  }
  bool was_drop = false;
  {
    rt::PiLock lock(mutex_);
    was_drop = slots_[static_cast<std::size_t>(index)].order == UINT64_MAX;
    slots_[static_cast<std::size_t>(index)].order = next_order_++;
    slots_[static_cast<std::size_t>(index)].state = SlotState::kReady;
    ++ready_count_;
    bump(sent_);
  }
  ready_cv_.notify_one();
  return was_drop ? SendStatus::kOkDroppedOlder : SendStatus::kOk;
}

SendStatus Mailbox::try_send_bytes(std::span<const std::byte> message) noexcept {
  if (message.size() < sizeof(MessageHeader)) return SendStatus::kTooLarge;
  MessageHeader header;
  std::memcpy(&header, message.data(), sizeof header);
  const ConstBuffer body{message.data() + sizeof header, message.size() - sizeof header};
  return try_send(header, {body});
}

int Mailbox::wait_ready_locked(int64_t timeout_ns, RecvStatus& status) noexcept {
  const int64_t deadline = deadline_for(timeout_ns);
  for (;;) {
    const int next = find_next_locked();
    if (next >= 0) return next;
    if (closed_) {
      status = RecvStatus::kClosed;
      return -1;
    }
    if (wakeups_ > 0) {
      --wakeups_;
      status = RecvStatus::kTimeout;
      return -1;
    }
    if (timeout_ns == kNonBlocking) {
      status = RecvStatus::kEmpty;
      return -1;
    }
    if (!ready_cv_.wait_until(mutex_, deadline) && find_next_locked() < 0) {
      status = RecvStatus::kTimeout;
      return -1;
    }
  }
}

void Mailbox::free_slot(int index) noexcept { slots_[static_cast<std::size_t>(index)].state = SlotState::kFree; }

Mailbox::Received Mailbox::receive(std::span<std::byte> buffer, int64_t timeout_ns) noexcept {
  Received r;
  int index = -1;
  {
    rt::PiLock lock(mutex_);
    index = wait_ready_locked(timeout_ns, r.status);
    if (index < 0) return r;
    slots_[static_cast<std::size_t>(index)].state = SlotState::kReading;
    --ready_count_;
  }
  const std::byte* src = slot_data(index);
  std::memcpy(&r.header, src, sizeof r.header);
  if (r.header.length > buffer.size()) {
    r.status = RecvStatus::kTooSmall;
  } else {
    std::memcpy(buffer.data(), src, r.header.length);
    r.length = r.header.length;
    r.status = RecvStatus::kOk;
  }
  {
    rt::PiLock lock(mutex_);
    free_slot(index);
    bump(r.status == RecvStatus::kOk ? received_ : truncated_);
  }
  // The task timeline's hand-off (after the lock: nothing is held while it records).
  if (r.status == RecvStatus::kOk) {
    rt::trace::record(rt::trace::Kind::kReceive, 0, r.header.src, rt::trace::message_aux(r.header.type, r.header.seq),
                      r.header.dest);
  }
  return r;
}

Mailbox::Peeked Mailbox::peek(int64_t timeout_ns) noexcept {
  Peeked p;
  rt::PiLock lock(mutex_);
  if (peeked_ >= 0) {  // single reader: a second peek without peek_end gets the same message
    const std::byte* data = slot_data(peeked_);
    p.status = RecvStatus::kOk;
    p.header = reinterpret_cast<const MessageHeader*>(data);
    p.body = {data + sizeof(MessageHeader), p.header->length - sizeof(MessageHeader)};
    return p;
  }
  const int index = wait_ready_locked(timeout_ns, p.status);
  if (index < 0) return p;
  slots_[static_cast<std::size_t>(index)].state = SlotState::kReading;
  --ready_count_;
  peeked_ = index;
  const std::byte* data = slot_data(index);
  p.status = RecvStatus::kOk;
  // Slots are 8-byte aligned and start with the header.
  p.header = reinterpret_cast<const MessageHeader*>(data);
  p.body = {data + sizeof(MessageHeader), p.header->length - sizeof(MessageHeader)};
  // The task timeline's hand-off (a bounded store into the task's own ring).
  rt::trace::record(rt::trace::Kind::kReceive, 0, p.header->src, rt::trace::message_aux(p.header->type, p.header->seq),
                    p.header->dest);
  return p;
}

void Mailbox::peek_end() noexcept {
  rt::PiLock lock(mutex_);
  if (peeked_ < 0) return;
  free_slot(peeked_);
  peeked_ = -1;
  bump(received_);
}

bool Mailbox::wait(int64_t timeout_ns) noexcept {
  rt::PiLock lock(mutex_);
  RecvStatus status{};
  return wait_ready_locked(timeout_ns, status) >= 0;
}

void Mailbox::wake() noexcept {
  {
    rt::PiLock lock(mutex_);
    ++wakeups_;
  }
  ready_cv_.notify_all();
}

void Mailbox::close() noexcept {
  {
    rt::PiLock lock(mutex_);
    closed_ = true;
  }
  ready_cv_.notify_all();
}

void Mailbox::reopen() noexcept {
  rt::PiLock lock(mutex_);
  closed_ = false;
  wakeups_ = 0;
}

uint32_t Mailbox::queued() const noexcept {
  rt::PiLock lock(mutex_);
  return ready_count_;
}

MailboxCounters Mailbox::counters() const noexcept {
  MailboxCounters c;
  c.sent = sent_.load(std::memory_order_relaxed);
  c.received = received_.load(std::memory_order_relaxed);
  c.dropped = dropped_.load(std::memory_order_relaxed);
  c.refused = refused_.load(std::memory_order_relaxed);
  c.too_large = too_large_.load(std::memory_order_relaxed);
  c.truncated = truncated_.load(std::memory_order_relaxed);
  c.denied = denied_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace rack::tims
