// What a reader gets back from a file, computed from the asset and the write options without
// writing or reading the file: the fitter measures dozens of candidates that differ from each
// other in a stream or two, and needs the exact values a reader would see (quantisation
// included), not the file.
#pragma once

#include "atex/container.h"
#include "atex/model.h"
#include "atex/status.h"

namespace atex::container {

// Returns, bit for bit, the asset that DecodeAsset(EncodeAsset(asset, options), read) returns
// when read.read_stats == read_stats: every attribute stream as its encoding rounds it
// (ReadBackStream), the metadata and deformation configuration through their chunks' own
// round trip, the rest copied. Large streams use several threads.
// Errors: EncodeAsset's for an invalid asset or options (ValidateAsset; kOutOfRange for a value
// f16 cannot hold); kUnsupported for options it does not model (Draco positions): the caller
// then encodes and decodes.
StatusOr<Asset> DecodedAsWritten(const Asset& asset, const WriteOptions& options, bool read_stats);

// EncodeAsset's check of the write options (asset_writer.cc): kInvalidArgument, or
// kUnsupportedCodec for Draco in a build without it.
Status CheckWriteOptions(const WriteOptions& options);

}  // namespace atex::container
