// Import of 4DGaussians (hustvl/4DGaussians) checkpoints without Python.
//
// A 4DGaussians output folder holds `cfg_args` (the training arguments) and
// `point_cloud/iteration_N/{point_cloud.ply, deformation.pth, ...}`. The PLY
// holds the canonical Gaussians (INRIA 3DGS layout); `deformation.pth` is
// `torch.save(deform_network.state_dict())`: a zip archive whose
// `<name>/data.pkl` pickle describes tensors stored raw in `<name>/data/<key>`.
//
// The imported deformation field reproduces 4DGaussians' own forward pass
// with DeformForward (atex/deform.h): the AABB is kept as stored, (max, min)
// -> aabb_lo = aabb[0], aabb_hi = aabb[1]; time_scale = 1, time_offset = 0
// (4DGaussians feeds t in [0, 1] directly); channels, resolutions, multires,
// width and trunk depth come from the tensor shapes. A head is enabled when
// its weights exist and its no_d* flag is off. Keys the field does not use
// (timenet.*, the *_poc buffers) are ignored; variants this importer cannot
// reproduce (static_mlp or empty_voxel masks, apply_rotation, grid_pe,
// no_grid) fail with kUnsupported rather than import something different.
// deformation_table.pth and deformation_accum.pth are not read: upstream's
// renderer deforms every Gaussian.
//
// The .pth reader treats its input as hostile: the zip layer is atex/zip.h;
// the pickle is parsed by a small allow-list unpickler that executes nothing
// (see converters/src/fourdgs/torch_pickle.h); tensor shapes, strides and
// offsets are checked against their storages before anything is allocated.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"

namespace atex {

struct FourDgsImportOptions {
  // In a model folder: which point_cloud/iteration_N to import (-1: the highest).
  int iteration = -1;
  // Head switches (4DGaussians' ModelHiddenParams). Unset: read from cfg_args
  // (in the given folder or two levels above an iteration folder), else
  // 4DGaussians' defaults: no_dx = no_ds = no_dr = false, no_do = no_dshs = true.
  std::optional<bool> no_dx, no_ds, no_dr, no_do, no_dshs;
  bool read_cfg_args = true;
  uint64_t max_checkpoint_bytes = uint64_t{8} << 30;  // deformation.pth size limit
};

// Imports a 4DGaussians model folder or one of its iteration folders into an
// Asset (gaussians from point_cloud.ply, deformation from deformation.pth,
// metadata: bounds of the canonical positions, time range [0, 1], provenance
// and the head flags used in metadata.extra). Errors: kNotFound (files),
// the PLY reader's and the .pth reader's errors, kUnsupported (variants
// above, or an SH head whose 48 outputs do not match the PLY's SH degree),
// kOutOfRange (NaN/Inf in a tensor, naming the key and index).
StatusOr<Asset> ImportFourDGaussians(const std::string& folder_or_iteration_dir,
                                     const FourDgsImportOptions& options = {});

// ---------------------------------------------------------------------------
// The layers below, for tests, tools and fuzzing.

// One entry of a torch state_dict. Floating tensors (float32/64, float16,
// bfloat16) are materialised as contiguous float32 in `values` (row-major
// over `shape`); other dtypes keep their shape only.
struct TorchTensor {
  std::string name;
  std::string dtype;            // "float32", "float64", "float16", "bfloat16", "int64", ...
  std::vector<int64_t> shape;
  std::vector<float> values;    // [prod(shape)] for floating dtypes, else empty
  bool floating = false;
};

struct TorchStateDict {
  std::vector<TorchTensor> tensors;  // in the file's order
  const TorchTensor* Find(const std::string& name) const;
};

struct TorchReadLimits {
  uint64_t max_pickle_bytes = uint64_t{64} << 20;
  uint64_t max_tensors = 1u << 16;
  uint64_t max_elements = uint64_t{1} << 32;  // all materialised values together
};

// Parses a `torch.save(state_dict)` zip archive held in memory (`what` names
// it in messages). Errors: kBadMagic (not a zip; the pre-1.6 non-zip format
// gives kUnsupported), kCorrupt (missing data.pkl or storage records, sizes
// that disagree, strides or offsets outside the storage), kUnsupported
// (opcodes or globals outside the allow-list, big-endian half types),
// kLimitExceeded, kTruncated.
StatusOr<TorchStateDict> ReadTorchStateDict(const uint8_t* data, size_t size, const std::string& what,
                                            const TorchReadLimits& limits = {});

// The no_d* switches of 4DGaussians' ModelHiddenParams (true = head off).
struct FourDgsHeadFlags {
  bool no_dx = false;
  bool no_ds = false;
  bool no_dr = false;
  bool no_do = true;
  bool no_dshs = true;
};

// Builds the deformation field of a 4DGaussians state_dict for Gaussians with
// `sh_coeffs` SH coefficients per channel. Errors name the key and shape.
StatusOr<DeformationField> FourDgsFieldFromStateDict(const TorchStateDict& state, const FourDgsHeadFlags& flags,
                                                     int sh_coeffs, const std::string& what);

// Reads the head flags (and refuses the unsupported variants) from the text
// of a 4DGaussians `cfg_args` file, "Namespace(sh_degree=3, ..., no_dx=False, ...)".
// Flags absent from the text keep their value in `flags`.
Status ParseFourDgsCfgArgs(const std::string& text, FourDgsHeadFlags* flags);

}  // namespace atex
