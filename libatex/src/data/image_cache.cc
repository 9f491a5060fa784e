#include "data/image_cache.h"

namespace atex {

std::shared_ptr<const Image> ImageCache::Find(const std::string& key) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = index_.find(key);
  if (it == index_.end()) return nullptr;
  lru_.splice(lru_.begin(), lru_, it->second);
  return it->second->image;
}

std::shared_ptr<const Image> ImageCache::Insert(const std::string& key, std::shared_ptr<const Image> image) {
  const uint64_t size = image->bytes();
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = index_.find(key);
  if (it != index_.end()) {  // loaded concurrently by another thread: keep one copy
    lru_.splice(lru_.begin(), lru_, it->second);
    return it->second->image;
  }
  if (size > limit_) return image;
  lru_.push_front(Entry{key, image, size});
  index_[key] = lru_.begin();
  bytes_ += size;
  while (bytes_ > limit_ && !lru_.empty()) {
    const Entry& victim = lru_.back();
    bytes_ -= victim.bytes;
    index_.erase(victim.key);
    lru_.pop_back();
  }
  return image;
}

uint64_t ImageCache::bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bytes_;
}

}  // namespace atex
