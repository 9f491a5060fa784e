// The deterministic view schedules of the trainer.
#include "atex/train/schedule.h"

#include <algorithm>
#include <map>
#include <set>

#include <gtest/gtest.h>

namespace atex::train {
namespace {

TEST(CameraSchedule, EpochsArePermutationsAndTheSeedDecides) {
  CameraSchedule schedule(6666, 27);
  std::vector<int> seen(27, 0);
  for (int i = 0; i < 27; ++i) seen[schedule.ViewAt(27 + i)]++;
  for (int c : seen) EXPECT_EQ(c, 1);
  EXPECT_EQ(schedule.Views(5, 8).size(), 8u);
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

TEST(TimeBatchSchedule, TheSeedDecides) {
  const std::vector<double> times = PanopticTimes();
  TimeBatchSchedule schedule(6666, times), same(6666, times), other(1, times);
  for (int s : {0, 17, 31, 1000}) EXPECT_EQ(same.Views(s, 8), schedule.Views(s, 8)) << "step " << s;
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

TEST(ShareOfBatch, SharesPartitionTheBatchAndPreferHomeViews) {
  const std::vector<double> times = PanopticTimes();
  TimeBatchSchedule schedule(6666, times);
  for (int world : {1, 2, 4}) {
    size_t home_views = 0, views_total = 0;
    for (int s = 0; s < 200; ++s) {
      const std::vector<size_t> batch = schedule.Views(s, 8);
      std::multiset<size_t> joined;
      for (int r = 0; r < world; ++r) {
        const std::vector<size_t> mine = ShareOfBatch(batch, r, world);
        ASSERT_EQ(mine.size(), 8u / world) << "step " << s << " rank " << r;
        for (size_t v : mine) {
          joined.insert(v);
          home_views += HomeRank(v, world) == r;
          ++views_total;
        }
        // A view away from its home rank only where its home rank's share is full of home views.
        for (size_t v : mine) {
          if (HomeRank(v, world) == r) continue;
          const std::vector<size_t> home_share = ShareOfBatch(batch, HomeRank(v, world), world);
          for (size_t w : home_share) EXPECT_EQ(HomeRank(w, world), HomeRank(v, world)) << "step " << s;
        }
      }
      EXPECT_EQ(joined, std::multiset<size_t>(batch.begin(), batch.end())) << "step " << s << " world " << world;
    }
    if (world == 1) {
      EXPECT_EQ(home_views, views_total);
    }
    // Most views are rendered where their image is kept (a batch of 8 views of 2 or 4 homes).
    EXPECT_GT(static_cast<double>(home_views), 0.7 * static_cast<double>(views_total)) << "world " << world;
  }
  // Views by home rank, whatever the hash makes of the first indices.
  std::vector<size_t> home0, home1;
  for (size_t v = 0; home0.size() < 4 || home1.size() < 2; ++v) (HomeRank(v, 2) == 0 ? home0 : home1).push_back(v);
  // Every view of one home: its rank keeps the first two, the other rank takes the rest in order.
  EXPECT_EQ(ShareOfBatch(std::vector<size_t>(home0.begin(), home0.begin() + 4), 0, 2),
            (std::vector<size_t>{home0[0], home0[1]}));
  EXPECT_EQ(ShareOfBatch(std::vector<size_t>(home0.begin(), home0.begin() + 4), 1, 2),
            (std::vector<size_t>{home0[2], home0[3]}));
  // Two of each home, interleaved: every view is rendered at home.
  const std::vector<size_t> mixed = {home1[0], home0[0], home1[1], home0[1]};
  EXPECT_EQ(ShareOfBatch(mixed, 0, 2), (std::vector<size_t>{home0[0], home0[1]}));
  EXPECT_EQ(ShareOfBatch(mixed, 1, 2), (std::vector<size_t>{home1[0], home1[1]}));
}

}  // namespace
}  // namespace atex::train
