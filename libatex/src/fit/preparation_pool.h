// Worker threads for the plan's candidate preparations (plan.cc). Not part of the public API.
//
// BuildPlan prepares candidates (apply, encode, decode: CPU work) on several threads and scores
// them (probe renders) one at a time, in a fixed order. With a pool instead of a thread per
// candidate, the plan waits only for the candidate it scores next: the speculative preparations
// beside it (refreshes the lazy greedy may need later) go on in the background while it scores,
// and one that turns out unused is cancelled before it starts.
//
// Background workers keep speculative work from slowing what the plan waits for. A preparation
// is parallel inside (OpenMP loops, zstd workers), so urgent and speculative preparations running
// at once on threads of equal priority share every core, and each speculative one slows the
// urgent ones. Background workers run at the lowest scheduling priority (their OpenMP and zstd
// threads inherit it), so they take only the cores the urgent work leaves idle. On 16 cores
// (BENCHMARKS.md, issue 23) Panoptic uniform fits took 0.7-1.6 s less, adaptive ones 0.1-0.5 s
// more: a speculative preparation the plan then waits for keeps its low priority.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace atex::fit::internal {

class PreparationPool {
 public:
  class Task;

  // Starts up to `workers` threads and `background` background threads (fewer when the system
  // refuses one; with none, every task runs on the thread that finishes it). Background threads
  // lower their own scheduling priority (where the system allows; best effort) and run only
  // tasks that are not urgent; the others then run only urgent tasks. Without background
  // threads, the workers run every task, urgent ones first.
  explicit PreparationPool(size_t workers, size_t background = 0);
  // Cancels the tasks not started and waits for the running ones.
  ~PreparationPool();
  PreparationPool(const PreparationPool&) = delete;
  PreparationPool& operator=(const PreparationPool&) = delete;

  // Which queued jobs start first: urgent ones (the plan waits for them), in submission order;
  // then soon ones, latest first; then the later ones, in submission order.
  enum class Priority { kUrgent, kSoon, kLater };
  // Queues `job`. `job` must not throw (the plan's jobs catch and store their errors).
  std::shared_ptr<Task> Submit(std::function<void()> job, Priority priority);
  std::shared_ptr<Task> Submit(std::function<void()> job, bool urgent) {
    return Submit(std::move(job), urgent ? Priority::kUrgent : Priority::kLater);
  }
  // Returns once `task` has run; runs it on the calling thread when no worker has started it.
  // Precondition: `task` was not cancelled.
  void Finish(const std::shared_ptr<Task>& task);
  // A queued task starts before the tasks that are not urgent (the plan needs it now); no
  // effect on a task already started, finished or cancelled.
  void Promote(const std::shared_ptr<Task>& task);
  // A task not started never runs (its job is destroyed here); a running one finishes on its
  // worker. Either way nothing waits for it.
  void Cancel(const std::shared_ptr<Task>& task);
  // Waits until no task runs and none is queued.
  void WaitIdle();

  // The workers that run urgent tasks (the background threads not counted).
  size_t workers() const { return threads_.size() - background_; }
  size_t background_workers() const { return background_; }

 private:
  void Work(bool background);
  void RunLocked(const std::shared_ptr<Task>& task, std::unique_lock<std::mutex>* lock);

  std::mutex mutex_;
  std::condition_variable changed_;  // a task queued, started or finished; or stopping
  std::deque<std::shared_ptr<Task>> urgent_, later_;  // later_: the soon ones at its front
  size_t running_ = 0;
  size_t background_ = 0;  // threads_ ends with them
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace atex::fit::internal
