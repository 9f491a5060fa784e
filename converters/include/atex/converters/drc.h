// Google Draco point clouds (.drc): the Gaussian centres (canonical, or deformed
// to one time by the caller) with optional per-point attributes, e.g. for
// point-cloud tools and to compare Draco's position coding with the .atex codecs.
//
// Quantisation: positions are quantised by Draco to `position_bits` bits per axis
// over their bounding box (max error half a step: extent / (2^bits - 1) / 2);
// generic float attributes to `attribute_bits`; colours are 8-bit.
// Attributes (each named by Draco attribute metadata "name"):
//   POSITION   float x 3
//   COLOR      uint8 x 3  "color": sRGB-ish 0.5 + C0 * f_dc, clamped to [0, 1] (the view-independent colour)
//   GENERIC    float x 1  "opacity": sigmoid(logit)
//   GENERIC    float x 3  "log_scale"
//   GENERIC    float x 4  "rotation": unit quaternion (w, x, y, z)
// With the kd-tree method (the default, the smallest files) Draco reorders the
// points; all attributes follow the same order. The sequential method keeps the
// order.
// Needs Draco (ATEX_HAVE_DRACO); without it the functions return kUnsupportedCodec.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "atex/model.h"
#include "atex/status.h"

namespace atex {

struct DracoExportOptions {
  int position_bits = 16;   // 1..30
  int attribute_bits = 12;  // 1..30, for opacity, log_scale, rotation
  bool colors = false;
  bool opacity = false;
  bool scales = false;
  bool rotations = false;
  bool kd_tree = true;      // false: sequential encoding, point order preserved
  int encoding_speed = 5;   // Draco's 0 (smallest) .. 10 (fastest)
  int decoding_speed = 5;
};

// What DecodeDracoPointCloud found; attribute arrays are empty when absent.
struct DracoPointCloud {
  std::vector<float> positions;  // [N][3]
  std::vector<uint8_t> colors;   // [N][3]
  std::vector<float> opacity;    // [N]
  std::vector<float> log_scales; // [N][3]
  std::vector<float> rotations;  // [N][4] (w, x, y, z)
  size_t size() const { return positions.size() / 3; }
};

// Encodes the Gaussians' positions (and the requested attributes). kInvalidArgument
// for inconsistent arrays or options, kOutOfRange for NaN/Inf.
StatusOr<std::vector<uint8_t>> EncodeDracoPointCloud(const Gaussians& g, const DracoExportOptions& options = {});
// Encodes and writes atomically.
Status WriteDracoPointCloud(const std::string& path, const Gaussians& g, const DracoExportOptions& options = {});

// Decodes a Draco point cloud (used to verify exports and in benchmarks; Draco's
// own decoder checks the bitstream).
StatusOr<DracoPointCloud> DecodeDracoPointCloud(const uint8_t* data, size_t size);

}  // namespace atex
