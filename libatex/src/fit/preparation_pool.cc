// PreparationPool (preparation_pool.h).
#include "preparation_pool.h"

#include <algorithm>
#include <system_error>

#if defined(__linux__)
#include <sys/resource.h>
#include <unistd.h>
#endif

namespace atex::fit::internal {

class PreparationPool::Task {
 public:
  explicit Task(std::function<void()> job) : job(std::move(job)) {}
  enum class Phase { kQueued, kRunning, kDone, kCancelled };
  std::function<void()> job;
  Phase phase = Phase::kQueued;
};

namespace {

// The calling thread, and the threads it starts from now on (OpenMP's, zstd's), yield the CPU to
// every thread of normal priority. Linux only: there setpriority(PRIO_PROCESS) of a thread ID
// changes that thread alone (elsewhere it would change the whole process). A thread may always
// lower its own priority; nothing here raises it again, which would need privileges.
void LowerThisThreadsPriority() {
#if defined(__linux__)
  (void)setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 19);  // best effort: a refusal changes only timing
#endif
}

}  // namespace

PreparationPool::PreparationPool(size_t workers, size_t background) {
  threads_.reserve(workers + background);
  try {
    for (size_t i = 0; i < workers; ++i) threads_.emplace_back([this] { Work(false); });
    for (size_t i = 0; i < background; ++i) {
      threads_.emplace_back([this] {
        LowerThisThreadsPriority();
        Work(true);
      });
      std::lock_guard<std::mutex> lock(mutex_);  // read by the workers
      ++background_;
    }
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

void PreparationPool::Work(bool background) {
  std::unique_lock<std::mutex> lock(mutex_);
  // Background threads run the tasks that are not urgent, the others the urgent ones (and every
  // task when there are no background threads). While the constructor still starts background
  // threads, a worker may run a task that is not urgent: that changes only the order of work.
  const auto queue_for_me = [&]() -> std::deque<std::shared_ptr<Task>>* {
    if (background) return later_.empty() ? nullptr : &later_;
    if (!urgent_.empty()) return &urgent_;
    return background_ == 0 && !later_.empty() ? &later_ : nullptr;
  };
  while (true) {
    changed_.wait(lock, [&] { return stopping_ || queue_for_me() != nullptr; });
    if (stopping_) return;
    auto& queue = *queue_for_me();
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
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = std::find(later_.begin(), later_.end(), task);
    if (it == later_.end()) return;
    later_.erase(it);
    urgent_.push_back(task);
  }
  changed_.notify_all();  // a worker waiting for urgent work runs it now
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
    // The queued tasks nobody else runs: urgent ones without workers, any without threads.
    auto* queue = !urgent_.empty() && threads_.size() == background_ ? &urgent_
                  : !later_.empty() && threads_.empty()              ? &later_
                                                                     : nullptr;
    if (queue != nullptr) {
      std::shared_ptr<Task> task = std::move(queue->front());
      queue->pop_front();
      RunLocked(task, &lock);
      continue;
    }
    changed_.wait(lock);
  }
}

}  // namespace atex::fit::internal
