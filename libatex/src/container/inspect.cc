// InspectContainer and the size/histogram helpers behind `atex info`.
#include "atex/container.h"
#include "container/byte_io.h"
#include "container/codecs.h"
#include "container/draco_codec.h"
#include "container/format.h"
#include "container/layout.h"

namespace atex {

StatusOr<ContainerInfo> InspectContainer(const uint8_t* data, size_t size) {
  if (data == nullptr && size != 0) return MakeError(StatusCode::kInvalidArgument, "InspectContainer: null data");
  try {
    ATEX_ASSIGN_OR_RETURN(container::ParsedContainer parsed, container::ParseContainer(data, size, true));
    ContainerInfo info;
    info.version_major = parsed.version_major;
    info.version_minor = parsed.version_minor;
    info.flags = parsed.flags;
    info.file_size = parsed.file_size;
    for (const container::TocEntry& e : parsed.entries) {
      ChunkInfo c;
      c.type = e.type;
      c.flags = e.flags;
      c.codec = e.codec.codec;
      c.offset = e.offset;
      c.stored_size = e.stored_size;
      c.raw_size = e.raw_size;
      c.checksum = e.crc;
      c.known = container::FindChunkId(e.type) != container::ChunkId::kCount;
      c.codec_param = e.codec.element_size;
      c.codec_components = e.codec.components;
      c.codec_skip = e.codec.skip;
      info.chunks.push_back(std::move(c));
    }
    return info;
  } catch (const std::bad_alloc&) {
    return MakeError(StatusCode::kLimitExceeded, "out of memory inspecting a ", size, "-byte file");
  }
}

std::string CodecName(Codec codec) {
  switch (codec) {
    case Codec::kRaw: return "raw";
    case Codec::kZstd: return "zstd";
    case Codec::kShuffleZstd: return "shuffle-zstd";
    case Codec::kDeltaShuffleZstd: return "delta-shuffle-zstd";
    case Codec::kDraco: return "draco";
  }
  return StrCat("codec-", int{static_cast<uint8_t>(codec)});
}

std::string ScalarEncodingName(ScalarEncoding encoding) {
  switch (encoding) {
    case ScalarEncoding::kFloat32: return "f32";
    case ScalarEncoding::kFloat16: return "f16";
    case ScalarEncoding::kQuant16: return "q16";
    case ScalarEncoding::kQuant8: return "q8";
  }
  return StrCat("encoding-", int{static_cast<uint8_t>(encoding)});
}

StatusOr<ScalarEncoding> StreamEncodingOf(const uint8_t* data, size_t size, const ChunkInfo& chunk) {
  using container::ChunkId;
  const ChunkId id = container::FindChunkId(chunk.type);
  if (id == ChunkId::kCount || id == ChunkId::kMeta || id == ChunkId::kGhdr || id == ChunkId::kTlay ||
      id == ChunkId::kDcfg) {
    return MakeError(StatusCode::kInvalidArgument, "chunk '", chunk.type, "' is not an attribute stream");
  }
  uint64_t end = 0;
  if (container::AddOverflows(chunk.offset, chunk.stored_size, &end) || end > size) {
    return MakeError(StatusCode::kInvalidArgument, "chunk '", chunk.type, "' lies outside the given bytes");
  }
  const container::CodecParams params{chunk.codec, chunk.codec_param, chunk.codec_components, chunk.codec_skip};
  auto prefix = container::DecodeChunkPrefix(data + chunk.offset, static_cast<size_t>(chunk.stored_size),
                                             chunk.raw_size, params, 1);
  if (!prefix.ok()) return prefix.status().WithContext(StrCat("chunk '", chunk.type, "'"));
  if (prefix->empty() || (*prefix)[0] > static_cast<uint8_t>(ScalarEncoding::kQuant8)) {
    return MakeError(StatusCode::kCorrupt, "chunk '", chunk.type, "' has no valid stream encoding byte");
  }
  return static_cast<ScalarEncoding>((*prefix)[0]);
}

bool HaveDracoCodec() { return container::HaveDraco(); }

std::vector<ComponentSize> ComponentBytes(const ContainerInfo& info) {
  static constexpr const char* kOrder[] = {"header",   "metadata", "positions",   "rotations", "scales",  "opacities",
                                           "sh_dc",    "sh_rest",  "textures",    "deformation", "stats", "unknown"};
  std::vector<ComponentSize> groups;
  for (const char* name : kOrder) groups.push_back({name, 0});
  groups[0].bytes = container::kHeaderSize;
  for (const ChunkInfo& c : info.chunks) {
    const container::ChunkId id = container::FindChunkId(c.type);
    const std::string group = id == container::ChunkId::kCount ? "unknown" : container::TypeInfo(id).component;
    for (ComponentSize& g : groups) {
      if (g.component == group) g.bytes += container::kTocEntrySize + container::Align8(c.stored_size);
    }
  }
  std::vector<ComponentSize> present;
  for (ComponentSize& g : groups) {
    if (g.bytes > 0) present.push_back(std::move(g));
  }
  return present;
}

TextureHistogram ComputeTextureHistogram(const TexturePool& textures) {
  TextureHistogram h;
  h.gaussians = textures.size();
  const auto log2_side = [](uint8_t side) { return side >= 4 ? 2 : side >= 2 ? 1 : 0; };
  for (size_t i = 0; i < textures.size(); ++i) {
    h.counts[log2_side(textures.heights[i])][log2_side(textures.widths[i])] += 1;
    h.texels += uint64_t{textures.heights[i]} * textures.widths[i];
  }
  return h;
}

}  // namespace atex
