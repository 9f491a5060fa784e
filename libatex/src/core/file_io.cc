// Whole-file reads and atomic writes (POSIX). Errors name the path and the
// operating system's reason.
#include "atex/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <string>

namespace atex {

uint64_t PhysicalMemoryBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? uint64_t(pages) * uint64_t(page) : 0;
}

uint64_t MemoryLimit(uint64_t cap) {
  const uint64_t ram = PhysicalMemoryBytes();
  return ram > 0 ? std::min(cap, ram / 2) : cap;
}
namespace {

std::string ErrnoText(int err) { return std::strerror(err); }

Status IoError(const std::string& what, const std::string& path, int err) {
  return MakeError(err == ENOENT ? StatusCode::kNotFound : StatusCode::kIoError, what, " '", path,
                   "': ", ErrnoText(err));
}

// Closes a descriptor on scope exit.
class FdCloser {
 public:
  explicit FdCloser(int fd) : fd_(fd) {}
  ~FdCloser() {
    if (fd_ >= 0) ::close(fd_);
  }
  int Release() {
    const int fd = fd_;
    fd_ = -1;
    return fd;
  }

 private:
  int fd_;
};

std::string ParentDirectory(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

}  // namespace

StatusOr<std::vector<uint8_t>> ReadFileBytes(const std::string& path, uint64_t max_bytes) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return IoError("cannot open", path, errno);
  FdCloser closer(fd);
  struct stat info {};
  if (::fstat(fd, &info) != 0) return IoError("cannot stat", path, errno);
  if (S_ISDIR(info.st_mode)) return MakeError(StatusCode::kIoError, "'", path, "' is a directory");
  if (!S_ISREG(info.st_mode)) return MakeError(StatusCode::kIoError, "'", path, "' is not a regular file");
  const uint64_t size = static_cast<uint64_t>(info.st_size);
  if (size > max_bytes) {
    return MakeError(StatusCode::kLimitExceeded, "'", path, "' is ", size, " bytes, above the limit of ", max_bytes);
  }
  std::vector<uint8_t> bytes;
  try {
    bytes.resize(static_cast<size_t>(size));
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "cannot allocate ", size, " bytes to read '", path, "'");
  }
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t got = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (got < 0) {
      if (errno == EINTR) continue;
      return IoError(StrCat("cannot read (at byte ", done, ")"), path, errno);
    }
    if (got == 0) {
      return MakeError(StatusCode::kIoError, "'", path, "' shrank while being read (", done, " of ", size, " bytes)");
    }
    done += static_cast<size_t>(got);
  }
  return bytes;
}

Status WriteFileAtomic(const std::string& path, const void* data, size_t size) {
  if (path.empty()) return MakeError(StatusCode::kInvalidArgument, "empty output path");
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, "null data for '", path, "'");
  // A name unique within this process and across processes (pid), in the same
  // folder so that rename() is atomic.
  static std::atomic<unsigned> counter{0};
  const std::string temp = StrCat(path, ".tmp.", ::getpid(), ".", counter.fetch_add(1));
  const int fd = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd < 0) return IoError("cannot create", temp, errno);
  FdCloser closer(fd);
  auto fail = [&](const std::string& what, int err) {
    ::close(closer.Release());
    ::unlink(temp.c_str());
    return IoError(what, temp, err);
  };
  const auto* bytes = static_cast<const uint8_t*>(data);
  size_t done = 0;
  while (done < size) {
    const ssize_t wrote = ::write(fd, bytes + done, size - done);
    if (wrote < 0) {
      if (errno == EINTR) continue;
      return fail(StrCat("cannot write (at byte ", done, ")"), errno);
    }
    done += static_cast<size_t>(wrote);
  }
  if (::fsync(fd) != 0) return fail("cannot flush", errno);
  if (::close(closer.Release()) != 0) {
    const int err = errno;
    ::unlink(temp.c_str());
    return IoError("cannot close", temp, err);
  }
  if (::rename(temp.c_str(), path.c_str()) != 0) {
    const int err = errno;
    ::unlink(temp.c_str());
    return MakeError(StatusCode::kIoError, "cannot rename '", temp, "' to '", path, "': ", ErrnoText(err));
  }
  // Make the rename itself durable; failure here does not undo the write.
  const int dir = ::open(ParentDirectory(path).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
  return Status::Ok();
}

}  // namespace atex
