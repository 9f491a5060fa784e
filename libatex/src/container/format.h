// Constants of the .atex layout (format_spec/atex.md §3, §4, §7).
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

#include "atex/version.h"

namespace atex::container {

inline constexpr std::array<uint8_t, 8> kMagic = {0x89, 'A', 'T', 'E', 'X', 0x0D, 0x0A, 0x1A};
inline constexpr uint16_t kVersionMajor = kFormatVersionMajor;  // atex/version.h (cmake/version.h.in)
inline constexpr uint16_t kVersionMinor = kFormatVersionMinor;
inline constexpr uint64_t kHeaderSize = 32;
inline constexpr uint64_t kTocEntrySize = 48;

// Header field offsets.
inline constexpr size_t kHeaderMagic = 0, kHeaderMajor = 8, kHeaderMinor = 10, kHeaderFlags = 12,
                        kHeaderFileSize = 16, kHeaderChunkCount = 24, kHeaderCrc = 28;
// TOC entry field offsets.
inline constexpr size_t kTocType = 0, kTocFlags = 4, kTocCodec = 6, kTocParam = 7, kTocOffset = 8,
                        kTocStoredSize = 16, kTocRawSize = 24, kTocCrc = 32, kTocComponents = 36, kTocSkip = 40,
                        kTocReserved = 44;

inline constexpr uint16_t kChunkCritical = 1;

// Attribute stream header (§6).
inline constexpr uint64_t kStreamHeaderSize = 16;
inline constexpr size_t kStreamEncoding = 0, kStreamReserved8 = 1, kStreamComponents = 2, kStreamReserved32 = 4,
                        kStreamRows = 8;

inline constexpr uint64_t kGhdrSize = 16;
inline constexpr uint64_t kDcfgSize = 104;
inline constexpr int kDcfgMaxScales = 8;

// Chunk types of version 1.1 (GTWN is new in 1.1), in the order writers emit them.
enum class ChunkId : int {
  kMeta,
  kGhdr,
  kGpos,
  kGrot,
  kGscl,
  kGopa,
  kGsh0,
  kGshr,
  kGtwn,
  kTlay,
  kTexl,
  kDcfg,
  kDgrd,
  kDmlp,
  kGsta,
  kCount
};

struct ChunkTypeInfo {
  const char* type;       // four characters
  bool critical;
  bool required;          // in every file
  const char* component;  // ComponentBytes group
};

inline constexpr std::array<ChunkTypeInfo, static_cast<size_t>(ChunkId::kCount)> kChunkTypes = {{
    {"META", true, true, "metadata"},
    {"GHDR", true, true, "metadata"},
    {"GPOS", true, true, "positions"},
    {"GROT", true, true, "rotations"},
    {"GSCL", true, true, "scales"},
    {"GOPA", true, true, "opacities"},
    {"GSH0", true, true, "sh_dc"},
    {"GSHR", true, false, "sh_rest"},
    {"GTWN", true, false, "opacities"},
    {"TLAY", true, false, "textures"},
    {"TEXL", true, false, "textures"},
    {"DCFG", true, false, "deformation"},
    {"DGRD", true, false, "deformation"},
    {"DMLP", true, false, "deformation"},
    {"GSTA", false, false, "stats"},
}};

inline const ChunkTypeInfo& TypeInfo(ChunkId id) { return kChunkTypes[static_cast<size_t>(id)]; }

// The known chunk id of a four-character type, or kCount.
inline ChunkId FindChunkId(std::string_view type) {
  for (size_t i = 0; i < kChunkTypes.size(); ++i) {
    if (type == kChunkTypes[i].type) return static_cast<ChunkId>(i);
  }
  return ChunkId::kCount;
}

}  // namespace atex::container
