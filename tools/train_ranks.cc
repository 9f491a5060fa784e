#include "train_ranks.h"

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>
#include <thread>

#ifdef ATEX_HAVE_CUDA
#include "atex/cuda/nccl_communicator.h"
#endif

extern char** environ;

namespace atex::cli {
namespace {

// A TCP port that was free a moment ago (the kernel's pick for port 0).
StatusOr<int> FreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return MakeError(StatusCode::kIoError, "socket: ", std::strerror(errno));
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof(a);
  const bool ok = ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof(a)) == 0 &&
                  ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &length) == 0;
  ::close(fd);
  if (!ok) return MakeError(StatusCode::kIoError, "cannot find a free TCP port: ", std::strerror(errno));
  return static_cast<int>(ntohs(a.sin_port));
}

StatusOr<std::vector<std::string>> OwnCommandLine() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  if (!in) return MakeError(StatusCode::kIoError, "cannot read /proc/self/cmdline to start the ranks");
  const std::string all((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::string> args;
  size_t start = 0;
  for (size_t k = 0; k < all.size(); ++k) {
    if (all[k] == '\0') {
      args.push_back(all.substr(start, k - start));
      start = k + 1;
    }
  }
  if (args.empty()) return MakeError(StatusCode::kIoError, "/proc/self/cmdline is empty");
  return args;
}

}  // namespace

StatusOr<std::vector<int>> ParseGpuList(const std::string& text) {
  std::vector<int> ids;
  std::set<int> seen;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, comma - start);
    char* end = nullptr;
    const long id = std::strtol(item.c_str(), &end, 10);
    if (item.empty() || *end != '\0' || id < 0 || id > 1023) {
      return MakeError(StatusCode::kInvalidArgument, "--gpus '", text, "': '", item, "' is not a GPU index");
    }
    if (!seen.insert(static_cast<int>(id)).second) {
      return MakeError(StatusCode::kInvalidArgument, "--gpus '", text, "': GPU ", id, " is listed twice");
    }
    ids.push_back(static_cast<int>(id));
    start = comma + 1;
  }
  return ids;
}

bool MultiGpuAvailable() {
#ifdef ATEX_HAVE_CUDA
  return cuda::NcclAvailable();
#else
  return false;
#endif
}

StatusOr<int> LaunchGpuRanks(const std::vector<int>& gpus) {
  ATEX_ASSIGN_OR_RETURN(std::vector<std::string> args, OwnCommandLine());
  int port = 0;
  if (const char* p = std::getenv("MASTER_PORT"); p != nullptr && *p != '\0') {
    port = std::atoi(p);
  } else {
    ATEX_ASSIGN_OR_RETURN(port, FreePort());
  }
  const int world = static_cast<int>(gpus.size());
  std::vector<pid_t> children;
  for (int rank = 0; rank < world; ++rank) {
    const pid_t pid = ::fork();
    if (pid < 0) {
      for (pid_t c : children) ::kill(c, SIGTERM);
      return MakeError(StatusCode::kIoError, "fork: ", std::strerror(errno));
    }
    if (pid == 0) {
      ::setenv("RANK", std::to_string(rank).c_str(), 1);
      ::setenv("LOCAL_RANK", std::to_string(rank).c_str(), 1);
      ::setenv("WORLD_SIZE", std::to_string(world).c_str(), 1);
      ::setenv("MASTER_ADDR", "127.0.0.1", 1);
      ::setenv("MASTER_PORT", std::to_string(port).c_str(), 1);
      ::setenv("CUDA_VISIBLE_DEVICES", std::to_string(gpus[rank]).c_str(), 1);
      std::vector<char*> argv;
      for (std::string& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      ::execve("/proc/self/exe", argv.data(), environ);
      std::fprintf(stderr, "atex train: rank %d: cannot run /proc/self/exe: %s\n", rank, std::strerror(errno));
      ::_exit(127);
    }
    children.push_back(pid);
  }
  int result = 0;
  for (size_t left = children.size(); left > 0; --left) {
    int status = 0;
    const pid_t done = ::wait(&status);
    if (done < 0) break;
    const int code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
    if (code != 0 && result == 0) {
      result = code;
      // One rank failed: the others would wait for it in a collective. Stop them.
      for (pid_t c : children) {
        if (c != done) ::kill(c, SIGTERM);
      }
    }
  }
  return result;
}

StatusOr<std::unique_ptr<train::Communicator>> JoinLaunchedGroup(const train::LaunchEnvironment& env, int* device) {
  const char* visible = std::getenv("CUDA_VISIBLE_DEVICES");
  const bool one_visible = visible != nullptr && *visible != '\0' && std::strchr(visible, ',') == nullptr;
  *device = one_visible ? 0 : env.local_rank;
#ifdef ATEX_HAVE_CUDA
  auto comm = cuda::MakeNcclCommunicator(env, *device);
  if (!comm.ok()) return comm.status().WithContext("rank " + std::to_string(env.rank));
  return comm;
#else
  return MakeError(StatusCode::kUnsupported, "this build has no CUDA backend: cannot join a group of ",
                   env.world_size, " GPU ranks (RANK/WORLD_SIZE are set)");
#endif
}

Status RunThreadRanks(int ranks, const std::function<Status(int, train::Communicator&)>& body) {
  // A rank waits for rank 0's evaluations and colour fits between collectives: a generous limit,
  // which only a rank that never comes reaches.
  ATEX_ASSIGN_OR_RETURN(auto group, train::MakeInProcessGroup(ranks, std::chrono::hours(2)));
  std::vector<Status> results(ranks);
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r) threads.emplace_back([&, r] { results[r] = body(r, *group[r]); });
  for (std::thread& t : threads) t.join();
  if (!results[0].ok()) return results[0];
  for (int r = 1; r < ranks; ++r) {
    if (!results[r].ok()) return results[r].WithContext("rank " + std::to_string(r));
  }
  return Status::Ok();
}

}  // namespace atex::cli
