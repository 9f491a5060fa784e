// A thread-safe LRU cache of decoded images bounded by their pixel bytes. Not a
// public header (used by Dataset).
#pragma once

#include <cstdint>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <unordered_map>

#include "atex/image.h"

namespace atex {

class ImageCache {
 public:
  explicit ImageCache(uint64_t limit_bytes) : limit_(limit_bytes) {}

  // The cached image for `key`, or null (and the entry becomes most recent).
  std::shared_ptr<const Image> Find(const std::string& key);
  // Inserts (or returns the entry another thread inserted first), then evicts
  // least-recently-used entries until the total is within the limit. An image
  // larger than the whole limit is returned without being cached.
  std::shared_ptr<const Image> Insert(const std::string& key, std::shared_ptr<const Image> image);
  uint64_t bytes() const;

 private:
  struct Entry {
    std::string key;
    std::shared_ptr<const Image> image;
    uint64_t bytes;
  };
  uint64_t limit_;
  mutable std::mutex mutex_;
  std::list<Entry> lru_;  // most recent first
  std::unordered_map<std::string, std::list<Entry>::iterator> index_;
  uint64_t bytes_ = 0;
};

}  // namespace atex
