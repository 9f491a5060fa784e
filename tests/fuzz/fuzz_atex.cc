// libFuzzer target: the .atex reader (format_spec/atex.md) and, for inputs it
// accepts, the writer.
//
// Checksums are checked in one pass and skipped in another, so that mutated
// payloads reach the structural checks, the codecs and the value checks instead
// of stopping at a CRC mismatch. Properties checked beyond "no crash":
//   - an asset the reader accepts is valid, the writer can write it, and the
//     result reads back to an asset that encodes to the same bytes.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/container.h"

namespace {

atex::ReadOptions Options(bool verify) {
  atex::ReadOptions r;
  r.verify_checksums = verify;
  r.max_decoded_bytes = uint64_t{256} << 20;  // keep under libFuzzer's -rss_limit_mb
  return r;
}

void CheckWriterAccepts(const atex::Asset& asset) {
  if (!atex::ValidateAsset(asset).ok()) __builtin_trap();  // the reader returned an invalid asset
  auto bytes = atex::EncodeAsset(asset, {});
  if (!bytes.ok()) __builtin_trap();  // the writer refuses what the reader accepted
  auto again = atex::DecodeAsset(bytes->data(), bytes->size());
  if (!again.ok()) __builtin_trap();  // the writer produced an unreadable file
  auto twice = atex::EncodeAsset(*again, {});
  if (!twice.ok() || *twice != *bytes) __builtin_trap();  // f32 round trip is not exact
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  auto info = atex::InspectContainer(data, size);
  if (info.ok()) {
    for (const atex::ChunkInfo& chunk : info->chunks) (void)atex::StreamEncodingOf(data, size, chunk);
    (void)atex::ComponentBytes(*info);
  }
  (void)atex::DecodeAsset(data, size, Options(true));
  auto asset = atex::DecodeAsset(data, size, Options(false));
  if (asset.ok()) {
    CheckWriterAccepts(*asset);
    if (asset->textures) (void)atex::ComputeTextureHistogram(*asset->textures);
  }
  return 0;
}
