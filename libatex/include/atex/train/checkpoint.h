// Training checkpoints: a folder with the model (model.atex), the Adam moments
// (optimizer.bin: "ATEXOPT1", then per array a u64 element count and that many
// little-endian float32, in the order of OptimizerArrays) and the loop's own state
// (trainer.json: stage, phase, step, learning-rate scale, Adam step counts, config).
// The folder is written next to its destination and renamed into place.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::train {

struct Checkpoint {
  ModelState state;
  Metadata metadata;
  nlohmann::json trainer;  // the loop's state, as written
};

Status WriteCheckpoint(const std::string& dir, const ModelState& state, const Metadata& metadata,
                       const nlohmann::json& trainer);
StatusOr<Checkpoint> ReadCheckpoint(const std::string& dir);

}  // namespace atex::train
