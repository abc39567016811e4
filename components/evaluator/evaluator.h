// Evaluator (simulation): compares the robot's estimates with ChassisSim's true pose
// and publishes the localisation error (interfaces::EvaluatorData): Position (what
// the pilot steers on) and MCL (its estimate at each scan's time), each against the
// truth at the same moment. It is how the main job (configs/sim_mcl.yaml) shows its
// progress on rackd's --status lines and its result at exit, and what
// `rackctl get-data evaluator` answers.
//
// Triggered by its declared inputs: the chassis (every sample; its silence for
// silence_ms is an ERROR), Position (position_period_ms) and MCL, optional (cascading
// ON for all three; none of them moves the robot). Truth samples are kept in a fixed ring of the last 2 s; an estimate is
// compared with the truth sample nearest its time (within 20 ms).
//
// Real-time contract: on(), off() and loop() are RT-safe (fixed arrays, no
// allocation); describe_status() is not (rackd's main thread).
#pragma once

#include <array>
#include <atomic>
#include <cstdint>

#include "rack/core/data_component.h"
#include "evaluator_types.h"
#include "rack/interfaces/robot.h"

namespace rack::components {

class Evaluator final : public DataComponent<interfaces::EvaluatorData> {
 public:
  Evaluator();
  void describe_status(std::string& out) const override;

 protected:
  HookResult on() override;
  HookResult loop() override;  // RT, triggered by the three streams

 private:
  struct Truth {
    int64_t time_ns = 0;
    double x = 0.0, y = 0.0, phi = 0.0;
  };

 public:
  // Error statistics of one estimate stream: sums and a 1-mm histogram up to 10 m
  // (its last bucket open: p95 there is the largest error, an upper bound).
  // Public for its unit test; RT-safe (no allocation).
  struct ErrorStats {
    static constexpr std::size_t kBuckets = 10000;
    uint64_t n = 0;
    double sum_sq = 0.0, sum_sq_heading = 0.0, max = 0.0, last = 0.0;
    std::array<uint32_t, kBuckets> histogram{};
    void add(double error, double heading_error) noexcept;
    [[nodiscard]] double rms() const noexcept;
    [[nodiscard]] double heading_rms() const noexcept;
    [[nodiscard]] double p95() const noexcept;
  };

 private:
  const Truth* truth_at(int64_t time_ns) const noexcept;
  void evaluate(ErrorStats& stats, int64_t time_ns, double x, double y, double phi) noexcept;
  // One sample of an input; true when it counts (a truth sample, an estimate).
  bool take(const InputPort& from) noexcept;

  InputOf<interfaces::ChassisData>& chassis_;
  InputOf<interfaces::PositionData>& position_;
  InputOf<interfaces::MclData>& mcl_;

  static constexpr std::size_t kTruthSlots = 256;  // 2.5 s of a 100 Hz chassis
  std::array<Truth, kTruthSlots> truth_{};
  std::size_t truth_next_ = 0;
  std::size_t truth_count_ = 0;
  bool have_last_truth_ = false;
  Truth last_truth_{};
  ErrorStats position_stats_;
  ErrorStats mcl_stats_;
  interfaces::EvaluatorData data_{};
  // What describe_status() shows, for another thread: each value on its own (relaxed:
  // a status line may mix values of two consecutive samples, never a torn value).
  std::atomic<double> shown_distance_{0.0}, shown_position_rms_{0.0}, shown_position_max_{0.0},
      shown_position_error_{0.0}, shown_mcl_rms_{0.0}, shown_mcl_p95_{0.0}, shown_mcl_max_{0.0};
  std::atomic<uint64_t> shown_position_samples_{0}, shown_mcl_samples_{0};
};

}  // namespace rack::components
