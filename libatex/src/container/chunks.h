// Contents of the non-stream chunk types and the layouts of the deformation
// streams (format_spec/atex.md §7): META, GHDR, TLAY, DCFG, and the flattening
// of the HexPlane grids (DGRD) and MLP (DMLP).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"

namespace atex::container {

// META: compact JSON, keys sorted.
StatusOr<std::vector<uint8_t>> EncodeMeta(const Metadata& metadata);
// Refuses a byte-order mark and nesting deeper than 64 (kLimitExceeded) before
// parsing; bad JSON and wrong types are kCorrupt.
StatusOr<Metadata> DecodeMeta(const uint8_t* data, size_t size);

// GHDR: N and the SH degree.
struct GaussianHeader {
  uint64_t count = 0;
  int sh_degree = 0;
};
std::vector<uint8_t> EncodeGhdr(const GaussianHeader& header);
StatusOr<GaussianHeader> DecodeGhdr(const uint8_t* data, size_t size);

// TLAY: one byte per Gaussian (§7.4).
std::vector<uint8_t> EncodeTextureLayout(const TexturePool& textures);
// Fills heights, widths, axes and offsets of *textures (texels untouched);
// kOutOfRange names the Gaussian with a bad byte.
Status DecodeTextureLayout(const uint8_t* data, size_t size, uint64_t gaussian_count, TexturePool* textures);

// DCFG: 104 bytes (§7.5).
std::vector<uint8_t> EncodeDeformationConfig(const DeformationConfig& config);
StatusOr<DeformationConfig> DecodeDeformationConfig(const uint8_t* data, size_t size);

// Values in DGRD and DMLP implied by a (validated) configuration.
uint64_t GridValueCount(const DeformationConfig& config);
uint64_t MlpValueCount(const DeformationConfig& config);

// DGRD order: scale-major, planes xy..zt, each [C][res_b][res_a]. [G]
std::vector<float> FlattenGrids(const DeformationField& field);
// Precondition: grids.size() == GridValueCount(field->config).
void UnflattenGrids(const std::vector<float>& grids, DeformationField* field);

// DMLP order: trunk layers, then enabled heads' two layers; weight then bias. [P]
std::vector<float> FlattenMlp(const DeformationField& field);
// Precondition: mlp.size() == MlpValueCount(field->config).
void UnflattenMlp(const std::vector<float>& mlp, DeformationField* field);

}  // namespace atex::container
