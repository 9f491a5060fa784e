// Checks of a training config before anything trains (issue 24): every value in its
// documented range, and every setting that can contradict the dataset, the stages run
// or another setting cross-checked. Errors are numbered (status.h) and name the key and
// the value (and, for a contradiction, both settings); legal but suspicious combinations
// come back as warnings for the log and the report.
//
// To extend: a new key gets one line in the Validate* function of its section
// (config_check.cc); a new contradiction one block in CrossCheckConfig.
#pragma once

#include <string>
#include <vector>

#include "atex/dataset.h"
#include "atex/status.h"
#include "atex/train/config.h"

namespace atex::train {

// Ranges of every key: kOutOfRange "stage1.batch_size=0 is outside [1, 256]" (or
// kInvalidArgument for an unknown name, e.g. stage1.init_method). Needs no dataset.
Status ValidateConfig(const TrainConfig& config);

// Contradictions between settings, or with the dataset, for the stages that will run
// (`stages`: trainer.h's Stages bits, 1 = stage 1, 2 = stage 2): kInvalidArgument naming
// both sides. Appends warnings (one sentence each, naming the settings) to `warnings`.
// Calls ValidateConfig first.
Status CrossCheckConfig(const TrainConfig& config, const Dataset& dataset, int stages,
                        std::vector<std::string>* warnings);

// A resumed run continues the checkpoint's model: the settings that shape it (the
// deformation field's grid and MLP, the SH degree, the texture mode, the time bins of the
// growth statistics, the background, the seed) must equal the checkpoint's.
// kInvalidArgument naming the key and both values; the other keys (schedules, learning
// rates) may change and are listed in `changed` ("stage2.iterations: 20 -> 50").
Status CheckResumeConfig(const TrainConfig& checkpoint, const TrainConfig& requested,
                         std::vector<std::string>* changed);

}  // namespace atex::train
