// Communicators that need no transport (atex/train/communicator.h): one rank, and ranks as
// threads of one process meeting at a mutex and a condition variable.
#include "atex/train/communicator.h"

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <mutex>

namespace atex::train {

Status SingleRankCommunicator::Broadcast(void*, size_t, int root) {
  if (root != 0) return MakeError(StatusCode::kInvalidArgument, "broadcast root ", root, " is not a rank of 1");
  return Status::Ok();
}

Status BroadcastString(Communicator& comm, std::string* text, int root) {
  double length = comm.rank() == root ? static_cast<double>(text->size()) : 0.0;
  ATEX_RETURN_IF_ERROR(comm.Broadcast(&length, sizeof(length), root));
  text->resize(static_cast<size_t>(length));
  if (text->empty()) return Status::Ok();
  return comm.Broadcast(text->data(), text->size(), root);
}

namespace {

enum class Op { kSumFloat, kSumDouble, kMaxFloat, kBroadcast, kBarrier };

const char* OpName(Op op) {
  switch (op) {
    case Op::kSumFloat: return "AllReduceSum(float)";
    case Op::kSumDouble: return "AllReduceSum(double)";
    case Op::kMaxFloat: return "AllReduceMax(float)";
    case Op::kBroadcast: return "Broadcast";
    case Op::kBarrier: return "Barrier";
  }
  return "?";
}

// What one rank brought to the current collective.
struct Contribution {
  Op op = Op::kBarrier;
  void* data = nullptr;
  size_t count = 0;  // elements (bytes for Broadcast)
  int root = 0;
};

// The meeting point of a group. A collective has two halves: arrival (each rank leaves its
// contribution; the last to arrive checks that they agree and reduces in rank order into
// `result_`), then departure (each rank copies the result out; the last one opens the next
// collective). A rank arriving early for the next collective waits until the departure ends.
class Rendezvous {
 public:
  Rendezvous(int ranks, std::chrono::milliseconds timeout) : ranks_(ranks), timeout_(timeout), slots_(ranks) {}

  void Abort(int rank, const std::string& why) {
    std::lock_guard lock(mutex_);
    if (!broken_.ok()) return;
    broken_ = MakeError(StatusCode::kCancelled, "in-process communicator: rank ", rank, " stopped (", why,
                        "); the group is unusable");
    cv_.notify_all();
  }

  Status Run(int rank, const Contribution& mine) {
    std::unique_lock lock(mutex_);
    if (!broken_.ok()) return broken_;
    if (!cv_.wait_for(lock, timeout_, [&] { return !departing_ || !broken_.ok(); })) {
      return Break(rank, mine, "the previous collective to finish");
    }
    if (!broken_.ok()) return broken_;
    const uint64_t generation = generation_;
    slots_[rank] = mine;
    if (++arrived_ == ranks_) {
      status_ = Reduce();
      departing_ = true;
      cv_.notify_all();
    } else if (!cv_.wait_for(lock, timeout_,
                             [&] { return generation_ != generation || departing_ || !broken_.ok(); })) {
      return Break(rank, mine, "the other ranks");
    }
    // A collective that completed delivers its result even if a rank that already left it has
    // aborted since: that rank saw the result, so this one must too (two ranks reporting one
    // error, not one the error and the other "cancelled").
    if (!departing_) return broken_;
    const Status status = status_;
    if (status.ok()) CopyOut(rank);
    if (++departed_ == ranks_) {
      arrived_ = departed_ = 0;
      departing_ = false;
      ++generation_;
      cv_.notify_all();
    }
    return status;
  }

 private:
  Status Break(int rank, const Contribution& mine, const char* waiting_for) {
    broken_ = MakeError(StatusCode::kInternal, "in-process communicator: rank ", rank, " waited more than ",
                        timeout_.count(), " ms in ", OpName(mine.op), " of ", mine.count, " for ", waiting_for,
                        " (a rank skipped or reordered a collective); the group is unusable");
    cv_.notify_all();
    return broken_;
  }

  // Checks that every rank asked for the same collective, then reduces in rank order.
  Status Reduce() {
    const Contribution& first = slots_[0];
    for (int r = 1; r < ranks_; ++r) {
      const Contribution& c = slots_[r];
      if (c.op != first.op || c.count != first.count || c.root != first.root) {
        return MakeError(StatusCode::kInvalidArgument, "in-process communicator: rank 0 called ", OpName(first.op),
                         " of ", first.count, " (root ", first.root, ") but rank ", r, " called ", OpName(c.op),
                         " of ", c.count, " (root ", c.root, ")");
      }
    }
    switch (first.op) {
      case Op::kSumFloat: return Combine<float>([](float a, float b) { return a + b; });
      case Op::kSumDouble: return Combine<double>([](double a, double b) { return a + b; });
      case Op::kMaxFloat: return Combine<float>([](float a, float b) { return std::max(a, b); });
      case Op::kBroadcast:
        if (first.root < 0 || first.root >= ranks_) {
          return MakeError(StatusCode::kInvalidArgument, "broadcast root ", first.root, " is not a rank of ", ranks_);
        }
        result_.assign(static_cast<const char*>(slots_[first.root].data),
                       static_cast<const char*>(slots_[first.root].data) + first.count);
        return Status::Ok();
      case Op::kBarrier: return Status::Ok();
    }
    return MakeError(StatusCode::kInternal, "in-process communicator: unknown collective");
  }

  template <typename T, typename F>
  Status Combine(F combine) {
    const size_t count = slots_[0].count;
    result_.resize(count * sizeof(T));
    T* out = reinterpret_cast<T*>(result_.data());
    std::memcpy(out, slots_[0].data, count * sizeof(T));
    for (int r = 1; r < ranks_; ++r) {
      const T* in = static_cast<const T*>(slots_[r].data);
      for (size_t k = 0; k < count; ++k) out[k] = combine(out[k], in[k]);
    }
    return Status::Ok();
  }

  void CopyOut(int rank) {
    const Contribution& c = slots_[rank];
    if (c.op != Op::kBarrier && !result_.empty()) std::memcpy(c.data, result_.data(), result_.size());
  }

  const int ranks_;
  const std::chrono::milliseconds timeout_;
  std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Contribution> slots_;
  std::vector<char> result_;
  Status status_ = Status::Ok();
  Status broken_ = Status::Ok();
  int arrived_ = 0, departed_ = 0;
  bool departing_ = false;
  uint64_t generation_ = 0;
};

class InProcessCommunicator final : public Communicator {
 public:
  InProcessCommunicator(std::shared_ptr<Rendezvous> group, int rank, int ranks)
      : group_(std::move(group)), rank_(rank), ranks_(ranks) {}
  int rank() const override { return rank_; }
  int world_size() const override { return ranks_; }
  std::string name() const override { return "in-process"; }
  Status AllReduceSum(float* data, size_t count) override { return group_->Run(rank_, {Op::kSumFloat, data, count}); }
  Status AllReduceSum(double* data, size_t count) override {
    return group_->Run(rank_, {Op::kSumDouble, data, count});
  }
  Status AllReduceMax(float* data, size_t count) override { return group_->Run(rank_, {Op::kMaxFloat, data, count}); }
  Status Broadcast(void* bytes, size_t n, int root) override {
    return group_->Run(rank_, {Op::kBroadcast, bytes, n, root});
  }
  Status Barrier() override { return group_->Run(rank_, {Op::kBarrier, nullptr, 0}); }
  void Abort(const std::string& why) override { group_->Abort(rank_, why); }

 private:
  std::shared_ptr<Rendezvous> group_;
  int rank_, ranks_;
};

}  // namespace

StatusOr<std::vector<std::unique_ptr<Communicator>>> MakeInProcessGroup(int ranks, std::chrono::milliseconds timeout) {
  if (ranks < 1) return MakeError(StatusCode::kInvalidArgument, "an in-process group needs >= 1 rank, not ", ranks);
  auto group = std::make_shared<Rendezvous>(ranks, timeout);
  std::vector<std::unique_ptr<Communicator>> out;
  for (int r = 0; r < ranks; ++r) out.push_back(std::make_unique<InProcessCommunicator>(group, r, ranks));
  return out;
}

}  // namespace atex::train
