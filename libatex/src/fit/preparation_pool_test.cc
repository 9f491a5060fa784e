// PreparationPool (preparation_pool.h): order, cancellation, and tasks run by the caller.
#include "fit/preparation_pool.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <set>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#if defined(__linux__)
#include <sys/resource.h>
#include <unistd.h>
#endif

namespace atex::fit::internal {
namespace {

// Holds the pool's only worker until Open.
class Gate {
 public:
  void Pass() {
    std::unique_lock<std::mutex> lock(mutex_);
    entered_ = true;
    changed_.notify_all();
    changed_.wait(lock, [&] { return open_; });
  }
  void WaitEntered() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return entered_; });
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mutex_);
    open_ = true;
    changed_.notify_all();
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool entered_ = false, open_ = false;
};

TEST(PreparationPool, WithoutWorkersTheCallerRunsEachTask) {
  PreparationPool pool(0);
  EXPECT_EQ(pool.workers(), 0u);
  int a = 0, b = 0;
  auto first = pool.Submit([&] { a = 1; }, false);
  auto second = pool.Submit([&] { b = 2; }, true);
  pool.Finish(first);
  EXPECT_EQ(a, 1);
  EXPECT_EQ(b, 0);  // not waited for: not run
  pool.WaitIdle();
  EXPECT_EQ(b, 2);
}

TEST(PreparationPool, UrgentTasksStartFirstAndACancelledOneNeverRuns) {
  PreparationPool pool(1);
  Gate gate;
  std::mutex mutex;
  std::vector<int> order;
  const auto record = [&](int id) {
    return [&, id] {
      std::lock_guard<std::mutex> lock(mutex);
      order.push_back(id);
    };
  };
  auto blocker = pool.Submit([&] { gate.Pass(); }, true);
  gate.WaitEntered();  // the only worker is busy: the next tasks queue
  auto later = pool.Submit(record(1), false);
  auto held = std::make_shared<int>(7);
  auto cancelled = pool.Submit([&, held] { record(2)(); }, false);
  auto urgent = pool.Submit(record(3), true);
  auto soon = pool.Submit(record(4), PreparationPool::Priority::kSoon);
  auto sooner = pool.Submit(record(5), PreparationPool::Priority::kSoon);
  auto promoted = pool.Submit(record(6), false);
  pool.Promote(promoted);  // now urgent, after the urgent one queued before
  EXPECT_EQ(held.use_count(), 2);
  pool.Cancel(cancelled);
  EXPECT_EQ(held.use_count(), 1);  // the cancelled job is destroyed at once
  gate.Open();
  pool.WaitIdle();  // the worker runs the queue (WaitIdle runs nothing itself while there are workers)
  EXPECT_EQ(order, (std::vector<int>{3, 6, 5, 4, 1}));
  pool.Finish(later);  // done already: returns at once
}

TEST(PreparationPool, FinishRunsAQueuedTaskOnTheCaller) {
  PreparationPool pool(1);
  Gate gate;
  auto blocker = pool.Submit([&] { gate.Pass(); }, true);
  gate.WaitEntered();
  std::atomic<bool> ran{false};
  auto task = pool.Submit([&] { ran = true; }, false);
  pool.Finish(task);  // the worker is held: this thread runs it
  EXPECT_TRUE(ran);
  gate.Open();
  pool.Finish(blocker);
}

TEST(PreparationPool, DestroyingThePoolDropsQueuedTasksAndFinishesRunningOnes) {
  Gate gate;
  std::atomic<int> ran{0};
  auto held = std::make_shared<int>(1);
  {
    PreparationPool pool(1);
    pool.Submit([&] { gate.Pass(); ++ran; }, true);
    gate.WaitEntered();
    pool.Submit([&, held] { ran += 10; }, false);
    gate.Open();
  }
  EXPECT_EQ(ran.load() % 10, 1);  // the running task finished; the queued one may have started
  EXPECT_EQ(held.use_count(), 1);
}

TEST(PreparationPool, BackgroundThreadsRunOnlyTasksThatAreNotUrgentAndTheWorkersOnlyUrgentOnes) {
  PreparationPool pool(1, 1);
  ASSERT_EQ(pool.workers(), 1u);
  ASSERT_EQ(pool.background_workers(), 1u);
  std::mutex mutex;
  std::set<std::thread::id> urgent_ran_on, later_ran_on;
  const auto record = [&](std::set<std::thread::id>* on) {
    return [&, on] {
      std::lock_guard<std::mutex> lock(mutex);
      on->insert(std::this_thread::get_id());
    };
  };
  for (int i = 0; i < 200; ++i) {
    pool.Submit(record(i % 3 == 0 ? &urgent_ran_on : &later_ran_on), i % 3 == 0);
    pool.Submit(record(&later_ran_on),
                i % 2 == 0 ? PreparationPool::Priority::kSoon : PreparationPool::Priority::kLater);
    pool.Submit(record(&urgent_ran_on), true);
  }
  pool.WaitIdle();  // the threads run them all: WaitIdle runs nothing itself while both kinds have threads
  const std::thread::id caller = std::this_thread::get_id();
  ASSERT_EQ(urgent_ran_on.size(), 1u);
  ASSERT_EQ(later_ran_on.size(), 1u);
  EXPECT_NE(*urgent_ran_on.begin(), *later_ran_on.begin());
  EXPECT_NE(*urgent_ran_on.begin(), caller);
  EXPECT_NE(*later_ran_on.begin(), caller);
}

TEST(PreparationPool, WithOnlyBackgroundThreadsTheCallerRunsTheUrgentTasks) {
  PreparationPool pool(0, 1);
  EXPECT_EQ(pool.workers(), 0u);
  std::thread::id ran_on;
  pool.Submit([&] { ran_on = std::this_thread::get_id(); }, true);
  pool.WaitIdle();
  EXPECT_EQ(ran_on, std::this_thread::get_id());
}

TEST(PreparationPool, APromotedTaskWakesAnIdleWorker) {
  PreparationPool pool(1, 1);
  Gate gate;
  pool.Submit([&] { gate.Pass(); }, false);
  gate.WaitEntered();  // the background thread is busy; the worker waits for urgent work
  std::mutex mutex;
  std::condition_variable done;
  bool ran = false;
  auto task = pool.Submit(
      [&] {
        std::lock_guard<std::mutex> lock(mutex);
        ran = true;
        done.notify_all();
      },
      false);
  // Time for the worker, woken by that submission, to find nothing it runs and wait again (the
  // test passes either way when it is slower; it fails when the worker is left waiting).
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  pool.Promote(task);  // now urgent: the idle worker must take it, without Finish or WaitIdle
  {
    std::unique_lock<std::mutex> lock(mutex);
    // A guard against hanging, not a timing: the worker starts it at once.
    done.wait_for(lock, std::chrono::seconds(10), [&] { return ran; });
    EXPECT_TRUE(ran);
  }
  gate.Open();
  pool.WaitIdle();
}

#if defined(__linux__)
TEST(PreparationPool, BackgroundThreadsHaveTheLowestPriorityAndWorkersKeepTheirs) {
  const auto nice_of_this_thread = [] { return getpriority(PRIO_PROCESS, static_cast<id_t>(gettid())); };
  const int own = nice_of_this_thread();
  PreparationPool pool(1, 1);
  int worker_nice = -100, background_nice = -100;
  pool.Submit([&] { worker_nice = nice_of_this_thread(); }, true);
  pool.Submit([&] { background_nice = nice_of_this_thread(); }, false);
  pool.WaitIdle();
  EXPECT_EQ(worker_nice, own);
  EXPECT_EQ(background_nice, 19);
  EXPECT_EQ(nice_of_this_thread(), own);  // the process's other threads keep theirs
}
#endif

}  // namespace
}  // namespace atex::fit::internal
