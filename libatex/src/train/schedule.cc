#include "atex/train/schedule.h"

#include <cmath>
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

std::vector<size_t> CameraSchedule::Views(int64_t step, int batch, int rank, int world_size) const {
  const int local = batch / world_size;
  std::vector<size_t> views;
  views.reserve(local);
  const uint64_t start = static_cast<uint64_t>(step) * batch + static_cast<uint64_t>(rank) * local;
  for (int i = 0; i < local; ++i) views.push_back(ViewAt(start + i));
  return views;
}

}  // namespace atex::train
