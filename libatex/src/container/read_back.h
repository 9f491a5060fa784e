// What a reader gets back from a file, computed from the asset and the write options without
// writing or reading the file: the fitter measures dozens of candidates that differ from each
// other in a stream or two, and needs the exact values a reader would see (quantisation
// included), not the file.
#pragma once

#include <atomic>
#include <list>
#include <memory>
#include <mutex>
#include <vector>

#include "atex/container.h"
#include "atex/model.h"
#include "atex/status.h"
#include "container/fingerprint.h"

namespace atex::container {

// Remembers read-back streams by a fingerprint of their values and encoding (fingerprint.h:
// the encode cache's chance of a collision), so that a candidate that changes one stream reads
// back only that one; the others are copied. Keeps the `entries_per_stream` most recently used
// of each stream. Thread-safe.
class ReadBackCache {
 public:
  using Values = std::shared_ptr<const std::vector<float>>;
  explicit ReadBackCache(size_t entries_per_stream = 3) : entries_per_stream_(entries_per_stream) {}
  Values Find(int stream, const Fingerprint& key);  // null when absent
  void Add(int stream, const Fingerprint& key, Values values);
  uint64_t hits() const { return hits_; }
  uint64_t misses() const { return misses_; }

 private:
  struct Entry {
    int stream;
    Fingerprint key;
    Values values;
  };
  std::mutex mutex_;
  std::list<Entry> entries_;  // most recently used first
  size_t entries_per_stream_;
  std::atomic<uint64_t> hits_{0}, misses_{0};
};

// Returns, bit for bit, the asset that DecodeAsset(EncodeAsset(asset, options), read) returns
// when read.read_stats == read_stats: every attribute stream as its encoding rounds it
// (ReadBackStream), the metadata and deformation configuration through their chunks' own
// round trip, the rest copied. Large streams use several threads. Unlike DecodeAsset it has
// no file, so ReadOptions' limits on decoded size and expansion do not apply.
// Errors: EncodeAsset's for an invalid asset or options (ValidateAsset; kOutOfRange for a value
// f16 cannot hold); kUnsupported for options it does not model (Draco positions): the caller
// then encodes and decodes.
// With a cache, quantised and f16 streams whose values and encoding it has seen come from it.
StatusOr<Asset> DecodedAsWritten(const Asset& asset, const WriteOptions& options, bool read_stats,
                                 ReadBackCache* cache = nullptr);

// EncodeAsset's check of the write options (asset_writer.cc): kInvalidArgument, or
// kUnsupportedCodec for Draco in a build without it.
Status CheckWriteOptions(const WriteOptions& options);

}  // namespace atex::container
