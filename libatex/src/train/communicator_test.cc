// The communicators without a transport: one rank, and ranks as threads.
#include "atex/train/communicator.h"

#include <chrono>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace atex::train {
namespace {

// Runs body(rank, comm) on one thread per rank of a fresh in-process group.
std::vector<Status> RunRanks(int ranks, std::chrono::milliseconds timeout,
                             const std::function<Status(int, Communicator&)>& body) {
  auto group = MakeInProcessGroup(ranks, timeout);
  EXPECT_TRUE(group.ok()) << group.status().ToString();
  std::vector<Status> results(ranks);
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r) {
    threads.emplace_back([&, r] { results[r] = body(r, *(*group)[r]); });
  }
  for (std::thread& t : threads) t.join();
  return results;
}

TEST(Communicator, SingleRankLeavesDataAsItIs) {
  SingleRankCommunicator comm;
  std::vector<float> x = {1.5f, -2.0f};
  ASSERT_TRUE(comm.AllReduceSum(x.data(), x.size()).ok());
  ASSERT_TRUE(comm.AllReduceMax(x.data(), x.size()).ok());
  EXPECT_EQ(x, (std::vector<float>{1.5f, -2.0f}));
  EXPECT_TRUE(comm.Barrier().ok());
  EXPECT_TRUE(comm.Broadcast(x.data(), 8, 0).ok());
  EXPECT_EQ(comm.Broadcast(x.data(), 8, 1).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(comm.world_size(), 1);
}

TEST(Communicator, InProcessSumIsInRankOrderAndIdenticalOnEveryRank) {
  constexpr int kRanks = 3;
  std::vector<std::vector<float>> floats(kRanks);
  std::vector<std::vector<double>> doubles(kRanks);
  std::vector<std::vector<float>> maxima(kRanks);
  // A float sum that depends on the order: (1 + 1e8) + -1e8 = 0 in rank order, 1 + (1e8 + -1e8) = 1.
  const float inputs[kRanks] = {1.0f, 1e8f, -1e8f};
  auto results = RunRanks(kRanks, std::chrono::seconds(20), [&](int r, Communicator& comm) -> Status {
    floats[r] = {inputs[r], float(r + 1)};
    doubles[r] = {0.5 * r, 1e-3};
    maxima[r] = {float(r), -float(r)};
    ATEX_RETURN_IF_ERROR(comm.AllReduceSum(floats[r].data(), floats[r].size()));
    ATEX_RETURN_IF_ERROR(comm.AllReduceSum(doubles[r].data(), doubles[r].size()));
    return comm.AllReduceMax(maxima[r].data(), maxima[r].size());
  });
  for (int r = 0; r < kRanks; ++r) {
    ASSERT_TRUE(results[r].ok()) << results[r].ToString();
    EXPECT_EQ(floats[r][0], (1.0f + 1e8f) + -1e8f) << "rank order";
    EXPECT_EQ(floats[r][1], 6.0f);
    EXPECT_EQ(doubles[r], (std::vector<double>{1.5, 3e-3}));
    EXPECT_EQ(maxima[r], (std::vector<float>{2.0f, 0.0f}));
  }
}

TEST(Communicator, InProcessBroadcastCopiesTheRootsBytes) {
  constexpr int kRanks = 4;
  std::vector<std::string> texts(kRanks);
  auto results = RunRanks(kRanks, std::chrono::seconds(20), [&](int r, Communicator& comm) -> Status {
    if (r == 2) texts[r] = std::string(1000, 'x') + "from two";
    for (int i = 0; i < 50; ++i) ATEX_RETURN_IF_ERROR(comm.Barrier());  // many collectives in a row
    return BroadcastString(comm, &texts[r], 2);
  });
  for (int r = 0; r < kRanks; ++r) {
    ASSERT_TRUE(results[r].ok()) << results[r].ToString();
    EXPECT_EQ(texts[r], std::string(1000, 'x') + "from two");
  }
}

TEST(Communicator, InProcessMismatchedCountsFailOnEveryRank) {
  auto results = RunRanks(2, std::chrono::seconds(20), [&](int r, Communicator& comm) -> Status {
    std::vector<float> x(r == 0 ? 3 : 4, 1.0f);
    return comm.AllReduceSum(x.data(), x.size());
  });
  for (const Status& s : results) {
    EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
    EXPECT_NE(s.message().find("rank 1 called AllReduceSum(float) of 4"), std::string::npos) << s.ToString();
  }
}

TEST(Communicator, InProcessMismatchedOpsAndRootsFail) {
  auto ops = RunRanks(2, std::chrono::seconds(20), [&](int r, Communicator& comm) -> Status {
    std::vector<float> x(2, 1.0f);
    return r == 0 ? comm.AllReduceSum(x.data(), 2) : comm.AllReduceMax(x.data(), 2);
  });
  for (const Status& s : ops) EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
  auto roots = RunRanks(2, std::chrono::seconds(20), [&](int, Communicator& comm) -> Status {
    char byte = 0;
    return comm.Broadcast(&byte, 1, 5);
  });
  for (const Status& s : roots) EXPECT_EQ(s.code(), StatusCode::kInvalidArgument) << s.ToString();
}

TEST(Communicator, InProcessMissingRankTimesOutInsteadOfHanging) {
  auto results = RunRanks(3, std::chrono::milliseconds(200), [&](int r, Communicator& comm) -> Status {
    if (r == 1) return Status::Ok();  // rank 1 skips the collective
    std::vector<double> x(2, 1.0);
    Status first = comm.AllReduceSum(x.data(), x.size());
    if (first.ok()) return MakeError(StatusCode::kInternal, "a collective without rank 1 succeeded");
    // The group is broken: later calls fail at once.
    Status later = comm.Barrier();
    return later.ok() ? MakeError(StatusCode::kInternal, "a broken group still works") : first;
  });
  EXPECT_TRUE(results[1].ok());
  for (int r : {0, 2}) {
    EXPECT_EQ(results[r].code(), StatusCode::kInternal) << results[r].ToString();
    EXPECT_NE(results[r].message().find("waited more than 200 ms"), std::string::npos) << results[r].ToString();
  }
}

TEST(Communicator, AbortReleasesTheRanksThatWait) {
  auto results = RunRanks(2, std::chrono::seconds(60), [&](int r, Communicator& comm) -> Status {
    if (r == 1) {
      comm.Abort("a failing step");
      return Status::Ok();
    }
    return comm.Barrier();  // would wait a minute without the abort
  });
  EXPECT_EQ(results[0].code(), StatusCode::kCancelled) << results[0].ToString();
  EXPECT_NE(results[0].message().find("a failing step"), std::string::npos) << results[0].ToString();
}

// A rank that leaves a completed collective and aborts at once (its own step then failed)
// must not take the result away from a rank still waking up inside that collective: both saw
// the same reduction, so both go on to report the same error. Repeated, because which rank
// takes the lock first is the scheduler's choice.
TEST(Communicator, AnAbortAfterACollectiveDoesNotCancelItsResult) {
  for (int round = 0; round < 50; ++round) {
    std::vector<float> sums(2, 0.0f);
    auto results = RunRanks(2, std::chrono::seconds(60), [&](int r, Communicator& comm) -> Status {
      sums[r] = static_cast<float>(r + 1);
      if (r == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));  // rank 1 waits first
      ATEX_RETURN_IF_ERROR(comm.AllReduceSum(&sums[r], 1));
      if (r == 0) comm.Abort("rank 0's next step failed");
      return Status::Ok();
    });
    ASSERT_TRUE(results[1].ok()) << "round " << round << ": " << results[1].ToString();
    EXPECT_EQ(sums[0], 3.0f);
    EXPECT_EQ(sums[1], 3.0f);
  }
}

TEST(Communicator, InProcessGroupNeedsARank) {
  EXPECT_EQ(MakeInProcessGroup(0).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace atex::train
