// The deterministic view schedules of the trainer.
#include "atex/train/schedule.h"

#include <algorithm>
#include <map>
#include <set>

#include <gtest/gtest.h>

namespace atex::train {
namespace {

TEST(CameraSchedule, EpochsArePermutationsAndRanksPartitionTheBatch) {
  CameraSchedule schedule(6666, 27);
  std::vector<int> seen(27, 0);
  for (int i = 0; i < 27; ++i) seen[schedule.ViewAt(27 + i)]++;
  for (int c : seen) EXPECT_EQ(c, 1);
  // Two ranks of batch 8 see exactly the single-rank batch.
  auto all = schedule.Views(5, 8);
  auto r0 = schedule.Views(5, 8, 0, 2), r1 = schedule.Views(5, 8, 1, 2);
  r0.insert(r0.end(), r1.begin(), r1.end());
  EXPECT_EQ(all, r0);
  // Same seed, same stream; another seed differs.
  CameraSchedule same(6666, 27), other(1, 27);
  EXPECT_EQ(same.Views(3, 4), schedule.Views(3, 4));
  bool differs = false;
  for (int s = 0; s < 5; ++s) differs |= other.Views(s, 4) != schedule.Views(s, 4);
  EXPECT_TRUE(differs);
}

// 27 cameras x 30 times, as Panoptic basketball; views listed camera-major.
std::vector<double> PanopticTimes() {
  std::vector<double> times;
  for (int camera = 0; camera < 27; ++camera) {
    for (int t = 0; t < 30; ++t) times.push_back(t / 29.0);
  }
  return times;
}

TEST(TimeBatchSchedule, EachBatchIsOneTimeAndEveryTimeComesOncePerRound) {
  const std::vector<double> times = PanopticTimes();
  TimeBatchSchedule schedule(6666, times);
  ASSERT_EQ(schedule.time_count(), 30u);
  for (int round = 0; round < 3; ++round) {
    std::map<double, int> per_time;
    for (int s = round * 30; s < (round + 1) * 30; ++s) {
      const std::vector<size_t> views = schedule.Views(s, 4);
      ASSERT_EQ(views.size(), 4u);
      EXPECT_EQ(std::set<size_t>(views.begin(), views.end()).size(), 4u) << "step " << s << " repeats a view";
      for (size_t v : views) EXPECT_EQ(times[v], times[views[0]]) << "step " << s;
      ++per_time[times[views[0]]];
    }
    EXPECT_EQ(per_time.size(), 30u) << "round " << round;
  }
  // The cameras of one time vary between its steps.
  std::set<size_t> first_views;
  for (int s = 0; s < 300; ++s) first_views.insert(schedule.Views(s, 4)[0]);
  EXPECT_GT(first_views.size(), 200u);
}

TEST(TimeBatchSchedule, RanksPartitionTheBatchAndTheSeedDecides) {
  const std::vector<double> times = PanopticTimes();
  TimeBatchSchedule schedule(6666, times), same(6666, times), other(1, times);
  for (int s : {0, 17, 31, 1000}) {
    auto all = schedule.Views(s, 8);
    auto r0 = schedule.Views(s, 8, 0, 2), r1 = schedule.Views(s, 8, 1, 2);
    r0.insert(r0.end(), r1.begin(), r1.end());
    EXPECT_EQ(all, r0) << "step " << s;
    EXPECT_EQ(same.Views(s, 8), all);
  }
  bool differs = false;
  for (int s = 0; s < 5; ++s) differs |= other.Views(s, 4) != schedule.Views(s, 4);
  EXPECT_TRUE(differs);
}

TEST(TimeBatchSchedule, SmallTimeGroupsContinueWithTheNextTimes) {
  // One view per time (D-NeRF): a batch of 3 takes three distinct times.
  std::vector<double> mono;
  for (int t = 0; t < 10; ++t) mono.push_back(0.1 * t);
  TimeBatchSchedule schedule(3, mono);
  for (int s = 0; s < 20; ++s) {
    const std::vector<size_t> views = schedule.Views(s, 3);
    ASSERT_EQ(views.size(), 3u);
    EXPECT_EQ(std::set<size_t>(views.begin(), views.end()).size(), 3u) << "step " << s;
  }
  // Fewer views than the batch: every view, then repeats.
  TimeBatchSchedule tiny(3, std::vector<double>{0.0, 0.5});
  const std::vector<size_t> views = tiny.Views(0, 4);
  ASSERT_EQ(views.size(), 4u);
  EXPECT_EQ(std::set<size_t>(views.begin(), views.end()).size(), 2u);
}

}  // namespace
}  // namespace atex::train
