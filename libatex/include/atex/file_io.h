// Whole-file reads with a size cap, and atomic writes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/status.h"

namespace atex {

// Bytes of physical memory of this machine (sysconf); 0 when unknown.
uint64_t PhysicalMemoryBytes();
// The default cap of a decoder's output: `cap`, or half of the machine's RAM when that is
// smaller, so that a file declaring more than the machine can hold is refused with
// kLimitExceeded before the allocation rather than by the kernel's OOM killer or bad_alloc.
uint64_t MemoryLimit(uint64_t cap);

// Reads a whole file. Fails with kLimitExceeded (naming the size) if it is larger
// than max_bytes, kNotFound if it does not exist, kIoError otherwise.
StatusOr<std::vector<uint8_t>> ReadFileBytes(const std::string& path, uint64_t max_bytes = uint64_t{64} << 30);

// Writes `size` bytes to a temporary file in the destination folder, flushes it to
// disk and renames it over `path`. On any failure the temporary file is removed and
// an existing `path` is left untouched.
Status WriteFileAtomic(const std::string& path, const void* data, size_t size);
inline Status WriteFileAtomic(const std::string& path, const std::vector<uint8_t>& bytes) {
  return WriteFileAtomic(path, bytes.data(), bytes.size());
}

}  // namespace atex
