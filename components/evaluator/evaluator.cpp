#include "evaluator/evaluator.h"

#include <cmath>
#include <cstdio>

#include "common/pose2d.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

using interfaces::ChassisData;
using interfaces::MclData;
using interfaces::PositionData;

namespace {
constexpr int64_t kMatchWindowNs = 20 * rt::kNsPerMs;
}  // namespace

void Evaluator::ErrorStats::add(double error, double heading_error) noexcept {
  ++n;
  last = error;
  sum_sq += error * error;
  sum_sq_heading += heading_error * heading_error;
  if (error > max) max = error;
  const double mm = error * 1000.0;
  const std::size_t bucket = mm >= static_cast<double>(kBuckets - 1) ? kBuckets - 1 : static_cast<std::size_t>(mm);
  ++histogram[bucket];
}

double Evaluator::ErrorStats::rms() const noexcept { return n > 0 ? std::sqrt(sum_sq / static_cast<double>(n)) : 0.0; }

double Evaluator::ErrorStats::heading_rms() const noexcept {
  return n > 0 ? std::sqrt(sum_sq_heading / static_cast<double>(n)) : 0.0;
}

double Evaluator::ErrorStats::p95() const noexcept {
  if (n == 0) return 0.0;
  const auto target = static_cast<uint64_t>(std::ceil(0.95 * static_cast<double>(n)));
  uint64_t seen = 0;
  for (std::size_t i = 0; i < kBuckets; ++i) {
    seen += histogram[i];
    // The bucket's upper edge; the last bucket is open (10 m and more), whose honest
    // upper bound is the largest error seen, not a silent 10 m.
    if (seen >= target) return i + 1 < kBuckets ? static_cast<double>(i + 1) / 1000.0 : max;
  }
  return max;
}

Evaluator::Evaluator()
    : DataComponent(DataTaskMode::kTriggered),
      chassis_(declare_input<ChassisData>("chassis",
                                          {.doc = "the ChassisSim whose true pose (truth_x/y/phi) is the reference"})),
      position_(declare_input<PositionData>("position", {.doc = "Position component to evaluate",
                                                         .optional = true,
                                                         .ask_period = true,
                                                         .period_ms = 100.0,
                                                         .watched = false})),
      mcl_(declare_input<MclData>("mcl", {.doc = "MCL component to evaluate", .optional = true, .watched = false})) {}

HookResult Evaluator::on() {
  truth_next_ = truth_count_ = 0;
  have_last_truth_ = false;
  position_stats_ = ErrorStats{};
  mcl_stats_ = ErrorStats{};
  data_ = interfaces::EvaluatorData{};
  return HookResult::kOk;
}

const Evaluator::Truth* Evaluator::truth_at(int64_t time_ns) const noexcept {
  const Truth* best = nullptr;
  int64_t best_gap = kMatchWindowNs + 1;
  for (std::size_t i = 0; i < truth_count_; ++i) {
    const Truth& t = truth_[i];
    const int64_t gap = t.time_ns > time_ns ? t.time_ns - time_ns : time_ns - t.time_ns;
    if (gap < best_gap) {
      best_gap = gap;
      best = &t;
    }
  }
  return best;
}

void Evaluator::evaluate(ErrorStats& stats, int64_t time_ns, double x, double y, double phi) noexcept {
  const Truth* t = truth_at(time_ns);
  if (t == nullptr || !std::isfinite(x) || !std::isfinite(y) || !std::isfinite(phi)) {
    ++data_.unmatched;
    return;
  }
  stats.add(std::hypot(x - t->x, y - t->y), std::abs(normalize_angle(phi - t->phi)));
}

// One sample of an input: the chassis' true pose, Position's or MCL's estimate.
bool Evaluator::take(const InputPort& from) noexcept {
  if (&from == &chassis_) {
    const ChassisData& c = chassis_.value();
    if (c.truth_valid == 0) return false;
    if (have_last_truth_) data_.distance += std::hypot(c.truth_x - last_truth_.x, c.truth_y - last_truth_.y);
    last_truth_ = Truth{chassis_.time_ns(), c.truth_x, c.truth_y, c.truth_phi};
    have_last_truth_ = true;
    truth_[truth_next_] = last_truth_;
    truth_next_ = (truth_next_ + 1) % kTruthSlots;
    if (truth_count_ < kTruthSlots) ++truth_count_;
  } else if (&from == &position_) {
    const PositionData& d = position_.value();
    evaluate(position_stats_, position_.time_ns(), d.x, d.y, d.phi);
  } else {
    const MclData& d = mcl_.value();
    evaluate(mcl_stats_, d.scan_time_ns != 0 ? d.scan_time_ns : mcl_.time_ns(), d.x, d.y, d.phi);
  }
  return true;
}

HookResult Evaluator::loop() {
  bool got = false;
  const Received r = receive([&](const InputPort& from) { got = take(from) || got; });
  if (r.failed) return HookResult::kError;  // a producer left ENABLED, or the chassis fell silent: retry
  if (!got) return HookResult::kOk;
  data_.position_samples = position_stats_.n;
  data_.position_error = position_stats_.last;
  data_.position_rms = position_stats_.rms();
  data_.position_p95 = position_stats_.p95();
  data_.position_max = position_stats_.max;
  data_.position_heading_rms = position_stats_.heading_rms();
  data_.mcl_samples = mcl_stats_.n;
  data_.mcl_error = mcl_stats_.last;
  data_.mcl_rms = mcl_stats_.rms();
  data_.mcl_p95 = mcl_stats_.p95();
  data_.mcl_max = mcl_stats_.max;
  data_.mcl_heading_rms = mcl_stats_.heading_rms();
  publish(data_, rt::host_time_ns());
  shown_distance_.store(data_.distance, std::memory_order_relaxed);
  shown_position_samples_.store(data_.position_samples, std::memory_order_relaxed);
  shown_position_error_.store(data_.position_error, std::memory_order_relaxed);
  shown_position_rms_.store(data_.position_rms, std::memory_order_relaxed);
  shown_position_max_.store(data_.position_max, std::memory_order_relaxed);
  shown_mcl_samples_.store(data_.mcl_samples, std::memory_order_relaxed);
  shown_mcl_rms_.store(data_.mcl_rms, std::memory_order_relaxed);
  shown_mcl_p95_.store(data_.mcl_p95, std::memory_order_relaxed);
  shown_mcl_max_.store(data_.mcl_max, std::memory_order_relaxed);
  return HookResult::kOk;
}

void Evaluator::describe_status(std::string& out) const {
  char line[256];
  std::snprintf(line, sizeof line,
                "driven %.1f m; position error now %.3f m, RMS %.3f m, max %.3f m (%llu samples); "
                "MCL error RMS %.3f m, p95 %s%.3f m, max %.3f m (%llu scans)",
                shown_distance_.load(std::memory_order_relaxed), shown_position_error_.load(std::memory_order_relaxed),
                shown_position_rms_.load(std::memory_order_relaxed),
                shown_position_max_.load(std::memory_order_relaxed),
                static_cast<unsigned long long>(shown_position_samples_.load(std::memory_order_relaxed)),
                shown_mcl_rms_.load(std::memory_order_relaxed),
                // Beyond the 10 m histogram p95 is the max: say it is a bound.
                shown_mcl_p95_.load(std::memory_order_relaxed) >= static_cast<double>(ErrorStats::kBuckets) / 1000.0
                    ? "at most "
                    : "",
                shown_mcl_p95_.load(std::memory_order_relaxed), shown_mcl_max_.load(std::memory_order_relaxed),
                static_cast<unsigned long long>(shown_mcl_samples_.load(std::memory_order_relaxed)));
  out += line;
}

}  // namespace rack::components
