#include "atex/train/schedule.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

namespace atex::train {

double SplitMix64::Normal() {
  double u1 = Uniform();
  while (u1 <= 0.0) u1 = Uniform();
  const double u2 = Uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

CameraSchedule::CameraSchedule(uint64_t seed, size_t view_count) : seed_(seed), view_count_(view_count) {}

std::vector<size_t> CameraSchedule::Permutation(uint64_t epoch) const {
  std::vector<size_t> order(view_count_);
  std::iota(order.begin(), order.end(), size_t{0});
  SplitMix64 rng(seed_ * 0x2545F4914F6CDD1Dull + epoch * 0x9E3779B97F4A7C15ull + 1);
  for (size_t i = order.size(); i > 1; --i) {  // Fisher-Yates
    const size_t j = static_cast<size_t>(rng.Next() % i);
    std::swap(order[i - 1], order[j]);
  }
  return order;
}

size_t CameraSchedule::ViewAt(uint64_t position) const {
  if (view_count_ == 0) return 0;
  const uint64_t epoch = position / view_count_;
  if (epoch != cached_epoch_) {
    cached_ = Permutation(epoch);
    cached_epoch_ = epoch;
  }
  return cached_[position % view_count_];
}

std::vector<size_t> CameraSchedule::Views(int64_t step, int batch) const {
  std::vector<size_t> views;
  if (batch <= 0) return views;
  views.reserve(static_cast<size_t>(batch));
  const uint64_t start = static_cast<uint64_t>(step) * static_cast<uint64_t>(batch);
  for (int i = 0; i < batch; ++i) views.push_back(ViewAt(start + static_cast<uint64_t>(i)));
  return views;
}

std::vector<size_t> ShareOfBatch(std::span<const size_t> batch, int rank, int world_size) {
  if (world_size <= 1) return std::vector<size_t>(batch.begin(), batch.end());
  const size_t share = batch.size() / static_cast<size_t>(world_size);
  // owner[i]: the rank that renders batch[i]; every rank computes the whole assignment.
  std::vector<int> owner(batch.size(), -1);
  std::vector<size_t> taken(static_cast<size_t>(world_size), 0);
  for (size_t i = 0; i < batch.size(); ++i) {
    const int home = HomeRank(batch[i], world_size);
    if (taken[static_cast<size_t>(home)] < share) owner[i] = home, ++taken[static_cast<size_t>(home)];
  }
  int next = 0;
  for (size_t i = 0; i < batch.size(); ++i) {
    if (owner[i] >= 0) continue;
    while (next < world_size && taken[static_cast<size_t>(next)] >= share) ++next;
    if (next == world_size) break;  // batch.size() not a multiple of world_size: the rest is nobody's
    owner[i] = next, ++taken[static_cast<size_t>(next)];
  }
  std::vector<size_t> mine;
  mine.reserve(share);
  for (size_t i = 0; i < batch.size(); ++i) {
    if (owner[i] == rank) mine.push_back(batch[i]);
  }
  return mine;
}

namespace {

// Fisher-Yates over `items` with `rng`.
void Shuffle(std::vector<size_t>& items, SplitMix64& rng) {
  for (size_t i = items.size(); i > 1; --i) {
    const size_t j = static_cast<size_t>(rng.Next() % i);
    std::swap(items[i - 1], items[j]);
  }
}

}  // namespace

TimeBatchSchedule::TimeBatchSchedule(uint64_t seed, std::span<const double> view_times) : seed_(seed) {
  std::map<double, std::vector<size_t>> by_time;
  for (size_t i = 0; i < view_times.size(); ++i) by_time[view_times[i]].push_back(i);
  for (auto& [time, views] : by_time) groups_.push_back(std::move(views));
}

const std::vector<size_t>& TimeBatchSchedule::TimeOrder(uint64_t epoch) const {
  if (epoch != cached_epoch_) {
    cached_.resize(groups_.size());
    std::iota(cached_.begin(), cached_.end(), size_t{0});
    // A stream apart from CameraSchedule's (the last constant differs), same seed.
    SplitMix64 rng(seed_ * 0x2545F4914F6CDD1Dull + epoch * 0x9E3779B97F4A7C15ull + 0x5851F42D4C957F2Dull);
    Shuffle(cached_, rng);
    cached_epoch_ = epoch;
  }
  return cached_;
}

std::vector<size_t> TimeBatchSchedule::Views(int64_t step, int batch) const {
  std::vector<size_t> picks;
  if (groups_.empty() || batch <= 0) return picks;
  const uint64_t times = groups_.size();
  const uint64_t s = static_cast<uint64_t>(step);
  SplitMix64 rng(seed_ * 0x9E3779B97F4A7C15ull + s * 0xD1B54A32D192ED03ull + 7);
  // Whole groups of the permutation, from the step's own position on, until B views are drawn.
  for (uint64_t k = 0; picks.size() < static_cast<size_t>(batch) && k < times; ++k) {
    const uint64_t position = s % times + k;
    std::vector<size_t> group = groups_[TimeOrder(s / times + position / times)[position % times]];
    Shuffle(group, rng);
    const size_t take = std::min(group.size(), static_cast<size_t>(batch) - picks.size());
    picks.insert(picks.end(), group.begin(), group.begin() + static_cast<std::ptrdiff_t>(take));
  }
  // Fewer views in the whole dataset than B: repeat them, as the epoch stream would.
  for (size_t i = 0; picks.size() < static_cast<size_t>(batch); ++i) {
    const size_t repeat = picks[i];  // a copy: push_back may reallocate
    picks.push_back(repeat);
  }
  return picks;
}

}  // namespace atex::train
