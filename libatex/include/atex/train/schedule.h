// Deterministic camera schedule: which training views each step (and each rank)
// uses, from the seed alone, so that paired runs see the same views in the same order.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace atex::train {

// An endless stream of epochs; each epoch is a permutation of [0, view_count)
// drawn from (seed, epoch) with a counter-based generator. Global step s with
// global batch B uses stream positions [s*B, (s+1)*B); rank r of R takes the
// contiguous slice of B/R positions starting at s*B + r*(B/R).
class CameraSchedule {
 public:
  CameraSchedule(uint64_t seed, size_t view_count);
  // View indices of `step` for `rank` of `world_size` (batch divisible by world_size).
  std::vector<size_t> Views(int64_t step, int batch, int rank = 0, int world_size = 1) const;
  // The view at absolute stream position `position`.
  size_t ViewAt(uint64_t position) const;

 private:
  std::vector<size_t> Permutation(uint64_t epoch) const;
  uint64_t seed_;
  size_t view_count_;
  mutable uint64_t cached_epoch_ = ~uint64_t{0};
  mutable std::vector<size_t> cached_;
};

// Batches of one time, for a deformation field that is evaluated once per distinct
// time of a batch (the CUDA backend shares that pass between the views of one time).
// Step s takes the time at position s mod T of a permutation of the T distinct
// training times drawn from (seed, s div T), so every time comes once per T steps, and
// B of that time's views drawn from (seed, s) without replacement. A time with fewer
// than B views is followed by the next times of the permutation (a dataset of one view
// per time, as D-NeRF, gets batches of B consecutive times of the permutation). Rank r
// of R takes the slice of B/R views starting at r*(B/R), as CameraSchedule.
class TimeBatchSchedule {
 public:
  // view_times[i]: the time of training view i; views of equal times form one group.
  TimeBatchSchedule(uint64_t seed, std::span<const double> view_times);
  std::vector<size_t> Views(int64_t step, int batch, int rank = 0, int world_size = 1) const;
  size_t time_count() const { return groups_.size(); }

 private:
  const std::vector<size_t>& TimeOrder(uint64_t epoch) const;  // cached: valid until the next call
  uint64_t seed_;
  std::vector<std::vector<size_t>> groups_;  // view indices per distinct time, ascending time
  mutable uint64_t cached_epoch_ = ~uint64_t{0};
  mutable std::vector<size_t> cached_;
};

// SplitMix64: the project's small deterministic generator (no std:: distribution,
// whose results differ between standard libraries).
struct SplitMix64 {
  uint64_t state;
  explicit SplitMix64(uint64_t seed) : state(seed) {}
  uint64_t Next() {
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  double Uniform() { return (Next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
  double Normal();  // Box-Muller
};

}  // namespace atex::train
