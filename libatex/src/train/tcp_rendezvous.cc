// Rank 0 hands a blob to every other rank over TCP (atex/train/tcp_rendezvous.h).
// Wire format, all integers big-endian: a peer sends "ATX1" and its rank (u32); rank 0 answers
// with the blob's length (u64) and its bytes.
#include "atex/train/tcp_rendezvous.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <thread>

namespace atex::train {
namespace {

using Clock = std::chrono::steady_clock;
constexpr char kMagic[4] = {'A', 'T', 'X', '1'};

// Closes a socket when it goes out of scope.
struct Socket {
  int fd = -1;
  explicit Socket(int f = -1) : fd(f) {}
  Socket(const Socket&) = delete;
  Socket& operator=(const Socket&) = delete;
  Socket(Socket&& o) noexcept : fd(o.fd) { o.fd = -1; }
  ~Socket() {
    if (fd >= 0) ::close(fd);
  }
};

Status SystemError(const std::string& what, const std::string& host, int port) {
  return MakeError(StatusCode::kIoError, "rendezvous at ", host, ":", port, ": ", what, ": ", std::strerror(errno));
}

int MillisecondsLeft(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
  return left > 0 ? static_cast<int>(std::min<long long>(left, 1 << 30)) : 0;
}

// Waits until `fd` is ready for `events` or the deadline passes.
Status WaitFor(int fd, short events, Clock::time_point deadline, const std::string& host, int port,
               const char* what) {
  while (true) {
    pollfd p{fd, events, 0};
    const int ready = ::poll(&p, 1, MillisecondsLeft(deadline));
    if (ready > 0) return Status::Ok();
    if (ready == 0) return MakeError(StatusCode::kIoError, "rendezvous at ", host, ":", port, ": timed out ", what);
    if (errno != EINTR) return SystemError(what, host, port);
  }
}

Status SendAll(int fd, const void* data, size_t n, Clock::time_point deadline, const std::string& host, int port) {
  const auto* p = static_cast<const char*>(data);
  while (n > 0) {
    ATEX_RETURN_IF_ERROR(WaitFor(fd, POLLOUT, deadline, host, port, "sending"));
    const ssize_t sent = ::send(fd, p, n, MSG_NOSIGNAL);
    if (sent < 0 && errno == EINTR) continue;
    if (sent <= 0) return SystemError("send", host, port);
    p += sent;
    n -= static_cast<size_t>(sent);
  }
  return Status::Ok();
}

Status ReceiveAll(int fd, void* data, size_t n, Clock::time_point deadline, const std::string& host, int port) {
  auto* p = static_cast<char*>(data);
  while (n > 0) {
    ATEX_RETURN_IF_ERROR(WaitFor(fd, POLLIN, deadline, host, port, "receiving"));
    const ssize_t got = ::recv(fd, p, n, 0);
    if (got < 0 && errno == EINTR) continue;
    if (got == 0) return MakeError(StatusCode::kIoError, "rendezvous at ", host, ":", port, ": the peer closed early");
    if (got < 0) return SystemError("recv", host, port);
    p += got;
    n -= static_cast<size_t>(got);
  }
  return Status::Ok();
}

void PutU64(uint64_t v, unsigned char* out) {
  for (int k = 7; k >= 0; --k, v >>= 8) out[k] = static_cast<unsigned char>(v & 0xff);
}
uint64_t GetU64(const unsigned char* in) {
  uint64_t v = 0;
  for (int k = 0; k < 8; ++k) v = (v << 8) | in[k];
  return v;
}

Status Serve(int port, int world_size, const std::vector<uint8_t>& blob, Clock::time_point deadline) {
  const std::string host = "0.0.0.0";
  Socket listener(::socket(AF_INET, SOCK_STREAM, 0));
  if (listener.fd < 0) return SystemError("socket", host, port);
  const int one = 1;
  ::setsockopt(listener.fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_ANY);
  address.sin_port = htons(static_cast<uint16_t>(port));
  if (::bind(listener.fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    return SystemError("bind (is the port in use?)", host, port);
  }
  if (::listen(listener.fd, world_size) != 0) return SystemError("listen", host, port);
  std::vector<bool> served(world_size, false);
  unsigned char header[8];
  PutU64(blob.size(), header);
  for (int peers = 0; peers < world_size - 1;) {
    ATEX_RETURN_IF_ERROR(WaitFor(listener.fd, POLLIN, deadline, host, port,
                                 ("waiting for ranks (" + std::to_string(peers) + " of " +
                                  std::to_string(world_size - 1) + " connected)").c_str()));
    Socket peer(::accept(listener.fd, nullptr, nullptr));
    if (peer.fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      return SystemError("accept", host, port);
    }
    unsigned char hello[8];
    ATEX_RETURN_IF_ERROR(ReceiveAll(peer.fd, hello, sizeof(hello), deadline, host, port));
    if (std::memcmp(hello, kMagic, 4) != 0) continue;  // not one of ours (a port scanner): ignore it
    const uint32_t rank =
        (uint32_t(hello[4]) << 24) | (uint32_t(hello[5]) << 16) | (uint32_t(hello[6]) << 8) | hello[7];
    if (rank == 0 || rank >= uint32_t(world_size) || served[rank]) {
      return MakeError(StatusCode::kInvalidArgument, "rendezvous at port ", port, ": a peer says it is rank ", rank,
                       (rank > 0 && rank < uint32_t(world_size) ? " again" : ""), " (world size ", world_size, ")");
    }
    ATEX_RETURN_IF_ERROR(SendAll(peer.fd, header, sizeof(header), deadline, host, port));
    ATEX_RETURN_IF_ERROR(SendAll(peer.fd, blob.data(), blob.size(), deadline, host, port));
    served[rank] = true;
    ++peers;
  }
  return Status::Ok();
}

// Connects to host:port, retrying while rank 0 is not listening yet.
StatusOr<Socket> Connect(const std::string& host, int port, Clock::time_point deadline) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  const std::string service = std::to_string(port);
  while (true) {
    addrinfo* found = nullptr;
    const int rc = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found);
    if (rc != 0) {
      return MakeError(StatusCode::kIoError, "rendezvous at ", host, ":", port, ": cannot resolve the host (",
                       ::gai_strerror(rc), ")");
    }
    for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
      Socket s(::socket(a->ai_family, a->ai_socktype, a->ai_protocol));
      if (s.fd >= 0 && ::connect(s.fd, a->ai_addr, a->ai_addrlen) == 0) {
        ::freeaddrinfo(found);
        return s;
      }
    }
    ::freeaddrinfo(found);
    if (MillisecondsLeft(deadline) == 0) return SystemError("connect (is rank 0 running?)", host, port);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

StatusOr<int> ParseEnv(const char* name, int fallback, int lo, int hi) {
  const char* v = std::getenv(name);
  if (v == nullptr || *v == '\0') return fallback;
  char* end = nullptr;
  errno = 0;
  const long value = std::strtol(v, &end, 10);
  if (errno != 0 || *end != '\0' || value < lo || value > hi) {
    return MakeError(StatusCode::kInvalidArgument, "environment variable ", name, "='", v,
                     "' is not an integer in [", lo, ", ", hi, "]");
  }
  return static_cast<int>(value);
}

}  // namespace

StatusOr<LaunchEnvironment> ReadLaunchEnvironment(bool* present) {
  LaunchEnvironment env;
  *present = std::getenv("RANK") != nullptr && std::getenv("WORLD_SIZE") != nullptr;
  ATEX_ASSIGN_OR_RETURN(env.world_size, ParseEnv("WORLD_SIZE", 1, 1, 1 << 20));
  ATEX_ASSIGN_OR_RETURN(env.rank, ParseEnv("RANK", 0, 0, env.world_size - 1));
  ATEX_ASSIGN_OR_RETURN(env.local_rank, ParseEnv("LOCAL_RANK", env.rank, 0, 1 << 20));
  ATEX_ASSIGN_OR_RETURN(env.master_port, ParseEnv("MASTER_PORT", env.master_port, 1, 65535));
  if (const char* addr = std::getenv("MASTER_ADDR"); addr != nullptr && *addr != '\0') env.master_addr = addr;
  return env;
}

Status ExchangeBlob(const std::string& host, int port, int rank, int world_size, std::vector<uint8_t>* blob,
                    std::chrono::milliseconds timeout) {
  if (world_size < 1 || rank < 0 || rank >= world_size) {
    return MakeError(StatusCode::kInvalidArgument, "rendezvous: rank ", rank, " of world size ", world_size);
  }
  if (port < 1 || port > 65535) return MakeError(StatusCode::kInvalidArgument, "rendezvous: port ", port);
  const Clock::time_point deadline = Clock::now() + timeout;
  if (rank == 0) return world_size == 1 ? Status::Ok() : Serve(port, world_size, *blob, deadline);
  ATEX_ASSIGN_OR_RETURN(Socket s, Connect(host, port, deadline));
  unsigned char hello[8] = {'A', 'T', 'X', '1', 0, 0, 0, 0};
  for (int k = 0; k < 4; ++k) hello[4 + k] = static_cast<unsigned char>((uint32_t(rank) >> (24 - 8 * k)) & 0xff);
  ATEX_RETURN_IF_ERROR(SendAll(s.fd, hello, sizeof(hello), deadline, host, port));
  unsigned char header[8];
  ATEX_RETURN_IF_ERROR(ReceiveAll(s.fd, header, sizeof(header), deadline, host, port));
  const uint64_t size = GetU64(header);
  if (size > (64u << 20)) {
    return MakeError(StatusCode::kLimitExceeded, "rendezvous at ", host, ":", port, ": a blob of ", size, " bytes");
  }
  blob->resize(size);
  return ReceiveAll(s.fd, blob->data(), blob->size(), deadline, host, port);
}

}  // namespace atex::train
