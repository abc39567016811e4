#include "rack/core/stepper.h"

#include <algorithm>
#include <climits>
#include <stdexcept>

#include "rack/core/executor.h"

namespace rack {

SteppedTask::~SteppedTask() {
  if (hooked && component.command_mailbox_) component.command_mailbox_->set_delivery_hook(nullptr);
}

void SteppedTask::delivered(tims::Mailbox& mailbox) noexcept {
  (void)mailbox;
  if (busy) return;  // a pass of this component runs: it takes the message after (see stepper.h)
  busy = true;
  (void)component.step_commands();
  busy = false;
}

// ExecutorOptions::stepped: instead of the threads of start_tasks(), the command
// mailbox is served in the sender's thread and the data task waits for a Stepper.
void Executor::add_stepped_task(ComponentView& v) {
  Component& c = *v.component;
  auto* dc = c.data_task_mode() != DataTaskMode::kNone ? dynamic_cast<DataComponentBase*>(&c) : nullptr;
  auto task = std::make_unique<SteppedTask>(c, dc);
  if (dc != nullptr) dc->begin_data_task();  // the first deadline counts from start(), as a thread's would
  c.command_mailbox_->set_delivery_hook(task.get());
  task->hooked = true;
  stepped_.push_back(std::move(task));
  v.tasks_started = true;  // it answers OFF at stop()
}

Stepper::Stepper(Executor& executor) : executor_(executor), clock_(rt::virtual_clock()) {
  if (!executor.options_.stepped) throw std::logic_error("Stepper: the executor is not stepped (ExecutorOptions)");
  if (!executor.started_) throw std::logic_error("Stepper: start() the executor first");
  if (clock_ == nullptr) throw std::logic_error("Stepper: install an rt::VirtualClock before the executor starts");
}

SteppedTask& Stepper::task_of(Component& component) {
  for (auto& t : executor_.stepped_) {
    if (&t->component == &component) return *t;
  }
  throw std::invalid_argument("Stepper: component '" + component.name() + "' is not in the stepped executor");
}

bool Stepper::step(const std::string& component) {
  Component* c = executor_.find(component);
  if (c == nullptr) throw std::invalid_argument("Stepper: no component '" + component + "'");
  return step(*c);
}

bool Stepper::step(Component& component) {
  SteppedTask& t = task_of(component);
  if (t.data == nullptr) throw std::invalid_argument("Stepper: component '" + component.name() + "' has no data task");
  return step_task(t);
}

bool Stepper::step_task(SteppedTask& t) {
  if (t.busy) return false;  // a step from inside a pass (a command handler's callback): not now
  t.busy = true;
  const bool ran = t.data != nullptr && t.data->step_data();
  // The command task's pass right after, as the thread wakes on report_loop_failure()
  // (and for what was sent to it during loop()).
  (void)t.component.step_commands();
  t.busy = false;
  return ran;
}

void Stepper::step_commands() {
  for (auto& t : executor_.stepped_) {
    if (t->busy) continue;
    t->busy = true;
    (void)t->component.step_commands();
    t->busy = false;
  }
}

int64_t Stepper::next_due_ns() const noexcept {
  int64_t next = INT64_MAX;
  for (const auto& t : executor_.stepped_) {
    const Component& c = t->component;
    if (c.loop_failed_.load(std::memory_order_acquire)) return clock_->now_ns();
    if (c.state() == ComponentState::kError && !c.init_failed_) next = std::min(next, c.retry_at_ns_);
    if (t->data != nullptr) next = std::min(next, t->data->next_data_step_ns());
  }
  return next;
}

uint64_t Stepper::run_due() {
  uint64_t cycles = 0;
  // Each pass either runs a cycle (a periodic deadline moves on, a waiting sample is
  // taken) or moves a task's state on (a renewal sent, a triggered task noticing it
  // was enabled); the bound only guards against a task that keeps itself due.
  for (int pass = 0; pass < 1000; ++pass) {
    const int64_t now = clock_->now_ns();
    bool any = false;
    for (auto& t : executor_.stepped_) {
      const Component& c = t->component;
      const bool command_due = c.loop_failed_.load(std::memory_order_acquire) ||
                               (c.state() == ComponentState::kError && !c.init_failed_ && c.retry_at_ns_ <= now);
      const bool data_due = t->data != nullptr && t->data->next_data_step_ns() <= now;
      if (!command_due && !data_due) continue;
      any = true;
      if (step_task(*t)) ++cycles;
    }
    if (!any) break;
  }
  return cycles;
}

uint64_t Stepper::run_until(int64_t t_ns) {
  uint64_t cycles = run_due();
  for (;;) {
    int64_t next = next_due_ns();
    const int64_t now = clock_->now_ns();
    if (next <= now) next = now + 1;  // due but not run (run_due's bound): time moves on
    if (next > t_ns) break;
    (void)clock_->advance_to(next);
    cycles += run_due();
  }
  (void)clock_->advance_to(t_ns);
  return cycles + run_due();
}

uint64_t Stepper::run_for(int64_t duration_ns) { return run_until(clock_->now_ns() + duration_ns); }

bool Stepper::run_until(const std::function<bool()>& done, int64_t limit_ns) {
  const int64_t end = clock_->now_ns() + limit_ns;
  (void)run_due();
  if (done()) return true;
  for (;;) {
    int64_t next = next_due_ns();
    const int64_t now = clock_->now_ns();
    if (next <= now) next = now + 1;
    if (next > end) {
      (void)clock_->advance_to(end);
      (void)run_due();
      return done();
    }
    (void)clock_->advance_to(next);
    (void)run_due();
    if (done()) return true;
  }
}

}  // namespace rack
