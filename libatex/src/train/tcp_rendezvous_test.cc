// The TCP rendezvous on 127.0.0.1: two processes (as two nodes would use it) and threads.
#include "atex/train/tcp_rendezvous.h"

#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <thread>

#include <gtest/gtest.h>

namespace atex::train {
namespace {

// A port that was free a moment ago (the kernel's choice for port 0).
int FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  EXPECT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)), 0);
  socklen_t length = sizeof(a);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &length);
  ::close(fd);
  return ntohs(a.sin_port);
}

std::vector<uint8_t> Blob() {
  std::vector<uint8_t> blob(128);  // the size of an ncclUniqueId
  for (size_t k = 0; k < blob.size(); ++k) blob[k] = static_cast<uint8_t>(k * 37 + 11);
  return blob;
}

TEST(TcpRendezvous, TwoProcessesExchangeTheBlob) {
  const int port = FreePort();
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {  // rank 1, possibly started before rank 0 listens: it retries
    std::vector<uint8_t> got;
    const Status s = ExchangeBlob("127.0.0.1", port, 1, 2, &got, std::chrono::seconds(20));
    ::_exit(s.ok() && got == Blob() ? 0 : 1);
  }
  std::vector<uint8_t> blob = Blob();
  const Status served = ExchangeBlob("127.0.0.1", port, 0, 2, &blob, std::chrono::seconds(20));
  int wstatus = 0;
  ASSERT_EQ(::waitpid(child, &wstatus, 0), child);
  ASSERT_TRUE(served.ok()) << served.ToString();
  ASSERT_TRUE(WIFEXITED(wstatus));
  EXPECT_EQ(WEXITSTATUS(wstatus), 0) << "rank 1 did not receive rank 0's blob";
}

TEST(TcpRendezvous, FourRanksAsThreadsByHostName) {
  const int port = FreePort();
  std::vector<std::vector<uint8_t>> blobs(4);
  std::vector<Status> results(4);
  blobs[0] = Blob();
  std::vector<std::thread> threads;
  for (int r = 3; r >= 0; --r) {  // the peers first: rank 0 comes last
    threads.emplace_back([&, r] {
      results[r] = ExchangeBlob("localhost", port, r, 4, &blobs[r], std::chrono::seconds(20));
    });
  }
  for (std::thread& t : threads) t.join();
  for (int r = 0; r < 4; ++r) {
    ASSERT_TRUE(results[r].ok()) << r << ": " << results[r].ToString();
    EXPECT_EQ(blobs[r], Blob()) << r;
  }
}

TEST(TcpRendezvous, APeerWithoutRankZeroTimesOut) {
  std::vector<uint8_t> blob;
  const Status s = ExchangeBlob("127.0.0.1", FreePort(), 1, 2, &blob, std::chrono::milliseconds(300));
  EXPECT_EQ(s.code(), StatusCode::kIoError) << s.ToString();
  EXPECT_NE(s.message().find("127.0.0.1"), std::string::npos) << s.ToString();
}

TEST(TcpRendezvous, RankZeroWithoutPeersTimesOut) {
  std::vector<uint8_t> blob = Blob();
  const Status s = ExchangeBlob("127.0.0.1", FreePort(), 0, 3, &blob, std::chrono::milliseconds(300));
  EXPECT_EQ(s.code(), StatusCode::kIoError) << s.ToString();
  EXPECT_NE(s.message().find("0 of 2 connected"), std::string::npos) << s.ToString();
}

TEST(TcpRendezvous, BadRanksAndEnvironmentAreRefused) {
  std::vector<uint8_t> blob;
  EXPECT_EQ(ExchangeBlob("127.0.0.1", 1234, 2, 2, &blob).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(ExchangeBlob("127.0.0.1", 0, 0, 2, &blob).code(), StatusCode::kInvalidArgument);
  ::setenv("WORLD_SIZE", "2", 1);
  ::setenv("RANK", "2", 1);
  bool present = false;
  auto env = ReadLaunchEnvironment(&present);
  EXPECT_EQ(env.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(env.status().message().find("RANK"), std::string::npos);
  ::setenv("RANK", "1", 1);
  ::setenv("MASTER_ADDR", "node7", 1);
  ::setenv("MASTER_PORT", "29611", 1);
  env = ReadLaunchEnvironment(&present);
  ASSERT_TRUE(env.ok()) << env.status().ToString();
  EXPECT_TRUE(present);
  EXPECT_EQ(env->rank, 1);
  EXPECT_EQ(env->world_size, 2);
  EXPECT_EQ(env->local_rank, 1);
  EXPECT_EQ(env->master_addr, "node7");
  EXPECT_EQ(env->master_port, 29611);
  for (const char* name : {"WORLD_SIZE", "RANK", "MASTER_ADDR", "MASTER_PORT"}) ::unsetenv(name);
  env = ReadLaunchEnvironment(&present);
  ASSERT_TRUE(env.ok());
  EXPECT_FALSE(present);
  EXPECT_EQ(env->world_size, 1);
}

}  // namespace
}  // namespace atex::train
