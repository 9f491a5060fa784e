// Deformation fields of the benchmarks: the trainer's documented defaults per dataset kind
// (train::DefaultConfig), so the benchmarks measure what `atex train` builds.
#pragma once

#include "atex/model.h"
#include "atex/train/config.h"

inline atex::DeformationConfig DatasetDeformation(const char* dataset_kind) {
  const atex::train::TrainConfig config = atex::train::DefaultConfig(dataset_kind);
  atex::DeformationConfig c = config.stage1.deformation;
  // The trainer sets the SH width from the Gaussians; only an enabled SH head needs it.
  c.sh_coeffs = c.heads[atex::kHeadSH] ? atex::ShCoeffCount(config.stage1.sh_degree) : 1;
  return c;
}
