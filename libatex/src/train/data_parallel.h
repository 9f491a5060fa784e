// The trainer's side of data parallelism (docs/multi_gpu.md): the collectives that keep the
// replicas of one model identical, built on a Communicator so that the loop stays readable and
// runs the same code at one rank. Internal to libatex/src/train.
#pragma once

#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"
#include "atex/train/communicator.h"

namespace atex::train {

// Element-wise sums of every tensor of a gradient (or parameter) set across the ranks, in a
// fixed order of tensors (collective).
Status AllReduceSum(Communicator& comm, Gaussians* g);
Status AllReduceSum(Communicator& comm, DeformationField* f);

// Sums the statistics of `kinds` (StatsKind bits) across the ranks: gradient sums, counts,
// demand, scale sums and importance are added, the largest screen radii take the maximum.
// Every rank's vectors must have the same sizes (kInvalidArgument otherwise, from the ranks'
// disagreement). Collective.
Status AllReduceStats(Communicator& comm, int kinds, TrainingStats* stats);

// A 64-bit content fingerprint (container/fingerprint.h) of the parameters (Gaussians, texels, deformation field),
// equal on two ranks exactly when their replicas are bit-identical (up to hash collisions).
uint64_t ParameterChecksum(const ModelState& state);

class DataParallel {
 public:
  // `comm` null: one rank (a SingleRankCommunicator of its own).
  explicit DataParallel(Communicator* comm) : comm_(comm != nullptr ? comm : &single_) {}
  Communicator& comm() { return *comm_; }
  int rank() const { return comm_->rank(); }
  int world_size() const { return comm_->world_size(); }
  // Rank 0 writes files, reports progress and evaluates.
  bool is_root() const { return comm_->rank() == 0; }

  // backend.ReadStats, then summed across the ranks (AllReduceStats). Collective.
  Status ReadStats(Backend& backend, int kinds, TrainingStats* stats);
  // Every rank's flag becomes rank 0's (decisions taken from rank 0's clock or callback).
  // Collective.
  Status AgreeWithRoot(bool* flag);
  // Rank 0's JSON value on every rank. Collective.
  Status BroadcastJson(nlohmann::json* value);
  // Compares the parameter checksums of the ranks; kInternal naming the ranks whose replica
  // differs from rank 0's and `where` (e.g. "fine step 300"): the replicas drifted, a bug of the
  // backend's reduction or a non-deterministic update. Collective.
  Status CheckReplicasAgree(Backend& backend, const std::string& where);

 private:
  SingleRankCommunicator single_;
  Communicator* comm_;
};

}  // namespace atex::train
