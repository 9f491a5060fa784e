// PreparationPool (preparation_pool.h).
#include "preparation_pool.h"

#include <algorithm>
#include <system_error>

namespace atex::fit::internal {

class PreparationPool::Task {
 public:
  explicit Task(std::function<void()> job) : job(std::move(job)) {}
  enum class Phase { kQueued, kRunning, kDone, kCancelled };
  std::function<void()> job;
  Phase phase = Phase::kQueued;
};

PreparationPool::PreparationPool(size_t workers) {
  threads_.reserve(workers);
  try {
    for (size_t i = 0; i < workers; ++i) threads_.emplace_back([this] { Work(); });
  } catch (const std::system_error&) {
    // No more threads: the ones started do the work, with the threads that finish tasks.
  }
}

PreparationPool::~PreparationPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
    for (auto* queue : {&urgent_, &later_}) {
      for (auto& task : *queue) task->phase = Task::Phase::kCancelled;
      queue->clear();
    }
  }
  changed_.notify_all();
  for (std::thread& t : threads_) t.join();
}

std::shared_ptr<PreparationPool::Task> PreparationPool::Submit(std::function<void()> job, Priority priority) {
  auto task = std::make_shared<Task>(std::move(job));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (priority == Priority::kUrgent) urgent_.push_back(task);
    if (priority == Priority::kSoon) later_.push_front(task);
    if (priority == Priority::kLater) later_.push_back(task);
  }
  changed_.notify_all();
  return task;
}

// Runs `task` (taken off its queue by the caller) with the lock released; `lock` is held again
// on return.
void PreparationPool::RunLocked(const std::shared_ptr<Task>& task, std::unique_lock<std::mutex>* lock) {
  task->phase = Task::Phase::kRunning;
  ++running_;
  std::function<void()> job = std::move(task->job);
  lock->unlock();
  job();
  job = nullptr;  // what the job holds is released before the task counts as done
  lock->lock();
  task->phase = Task::Phase::kDone;
  --running_;
  changed_.notify_all();
}

void PreparationPool::Work() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    changed_.wait(lock, [&] { return stopping_ || !urgent_.empty() || !later_.empty(); });
    if (stopping_) return;
    auto& queue = !urgent_.empty() ? urgent_ : later_;
    std::shared_ptr<Task> task = std::move(queue.front());
    queue.pop_front();
    RunLocked(task, &lock);
  }
}

void PreparationPool::Finish(const std::shared_ptr<Task>& task) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (task->phase == Task::Phase::kQueued) {
    for (auto* queue : {&urgent_, &later_}) {
      const auto it = std::find(queue->begin(), queue->end(), task);
      if (it != queue->end()) queue->erase(it);
    }
    RunLocked(task, &lock);
    return;
  }
  changed_.wait(lock, [&] { return task->phase == Task::Phase::kDone || task->phase == Task::Phase::kCancelled; });
}

void PreparationPool::Promote(const std::shared_ptr<Task>& task) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = std::find(later_.begin(), later_.end(), task);
  if (it == later_.end()) return;
  later_.erase(it);
  urgent_.push_back(task);
}

void PreparationPool::Cancel(const std::shared_ptr<Task>& task) {
  std::function<void()> dropped;  // destroyed after the lock is released
  std::lock_guard<std::mutex> lock(mutex_);
  if (task->phase != Task::Phase::kQueued) return;
  for (auto* queue : {&urgent_, &later_}) {
    const auto it = std::find(queue->begin(), queue->end(), task);
    if (it != queue->end()) queue->erase(it);
  }
  task->phase = Task::Phase::kCancelled;
  dropped = std::move(task->job);
}

void PreparationPool::WaitIdle() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    if (running_ == 0 && urgent_.empty() && later_.empty()) return;
    if (threads_.empty()) {
      // Nobody else runs the queued tasks.
      auto& queue = !urgent_.empty() ? urgent_ : later_;
      std::shared_ptr<Task> task = std::move(queue.front());
      queue.pop_front();
      RunLocked(task, &lock);
      continue;
    }
    changed_.wait(lock);
  }
}

}  // namespace atex::fit::internal
