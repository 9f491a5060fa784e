// Deterministic camera schedule: which training views each step uses, from the seed alone, so
// that paired runs see the same views in the same order, and which rank of a data-parallel group
// renders each of them (ShareOfBatch).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace atex::train {

// An endless stream of epochs; each epoch is a permutation of [0, view_count)
// drawn from (seed, epoch) with a counter-based generator. Global step s with
// global batch B uses stream positions [s*B, (s+1)*B).
class CameraSchedule {
 public:
  CameraSchedule(uint64_t seed, size_t view_count);
  // The view indices of `step`'s whole batch (all ranks'; ShareOfBatch splits it).
  std::vector<size_t> Views(int64_t step, int batch) const;
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
// per time, as D-NeRF, gets batches of B consecutive times of the permutation).
class TimeBatchSchedule {
 public:
  // view_times[i]: the time of training view i; views of equal times form one group.
  TimeBatchSchedule(uint64_t seed, std::span<const double> view_times);
  // The view indices of `step`'s whole batch (all ranks'; ShareOfBatch splits it).
  std::vector<size_t> Views(int64_t step, int batch) const;
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

// The home rank of training view `view` in a group of `world_size` ranks: the rank whose device
// keeps that view's target image. A hash of the index (SplitMix64), not the index modulo R, so that
// however a dataset orders its views (camera-major or time-major), each device holds about 1/R of
// the images and the views of one time spread over the ranks. (The generator's state starts one
// increment below view · 0x9E3779B97F4A7C15 + 0x632BE59BD9B4E019: the salt of the measured runs.)
inline int HomeRank(size_t view, int world_size) {
  if (world_size <= 1) return 0;
  SplitMix64 hash(static_cast<uint64_t>(view) * 0x9E3779B97F4A7C15ull + 0x632BE59BD9B4E019ull -
                  0x9E3779B97F4A7C15ull);
  return static_cast<int>(hash.Next() % static_cast<uint64_t>(world_size));
}

// The views that `rank` of `world_size` renders out of a step's whole batch `batch`
// (batch.size() a multiple of world_size; each rank gets batch.size() / world_size views).
// Each rank first takes its home views (HomeRank) in batch order, up to its share; the views
// left over, whose home rank is full, go in batch order to the ranks that still have room,
// lowest rank first. Every rank computes the same split from the same batch, and the shares
// partition the batch, so the ranks' summed gradients are those of one rank with all of it;
// only which device renders a view changes, and with it where its image must be.
std::vector<size_t> ShareOfBatch(std::span<const size_t> batch, int rank, int world_size);

}  // namespace atex::train
