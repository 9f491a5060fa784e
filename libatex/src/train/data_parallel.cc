// The collectives of data-parallel training (data_parallel.h).
#include "data_parallel.h"

#include <cstring>
#include <vector>

#include "container/fingerprint.h"

namespace atex::train {
namespace {

Status SumVector(Communicator& comm, std::vector<float>* v) { return comm.AllReduceSum(v->data(), v->size()); }

// Every float tensor of a deformation field, in a fixed order (the same on every rank).
template <typename Field, typename F>
void ForEachTensor(Field& f, F fn) {
  for (auto& scale : f.planes) {
    for (auto& plane : scale) fn(plane);
  }
  for (auto& layer : f.trunk) {
    fn(layer.weight);
    fn(layer.bias);
  }
  for (auto& head : f.heads) {
    for (auto& layer : head) {
      fn(layer.weight);
      fn(layer.bias);
    }
  }
}

}  // namespace

Status AllReduceSum(Communicator& comm, Gaussians* g) {
  for (std::vector<float>* v : {&g->positions, &g->rotations, &g->log_scales, &g->opacity_logits, &g->sh}) {
    ATEX_RETURN_IF_ERROR(SumVector(comm, v));
  }
  return Status::Ok();
}

Status AllReduceSum(Communicator& comm, DeformationField* f) {
  Status status = Status::Ok();
  ForEachTensor(*f, [&](std::vector<float>& v) {
    if (status.ok()) status = SumVector(comm, &v);
  });
  return status;
}

Status AllReduceStats(Communicator& comm, int kinds, TrainingStats* stats) {
  if (kinds & kStatsDensify) {
    ATEX_RETURN_IF_ERROR(SumVector(comm, &stats->densify.grad_norm_sum));
    ATEX_RETURN_IF_ERROR(SumVector(comm, &stats->densify.visible_count));
    ATEX_RETURN_IF_ERROR(comm.AllReduceMax(stats->densify.max_radius.data(), stats->densify.max_radius.size()));
  }
  if (kinds & kStatsTexture) {
    TextureStats& t = stats->texture;
    for (std::vector<float>* v : {&t.demand_sum, &t.visible_count, &t.scale_u_sum, &t.scale_v_sum}) {
      ATEX_RETURN_IF_ERROR(SumVector(comm, v));
    }
  }
  if (kinds & kStatsImportance) ATEX_RETURN_IF_ERROR(SumVector(comm, &stats->importance));
  return Status::Ok();
}

uint64_t ParameterChecksum(const ModelState& state) {
  container::FingerprintBuilder h;  // each vector a span of its own: lengths count
  const Gaussians& g = state.gaussians;
  for (const std::vector<float>* v : {&g.positions, &g.rotations, &g.log_scales, &g.opacity_logits, &g.sh}) h.Add(*v);
  if (state.textures) h.Add(state.textures->texels);
  if (state.deformation) {
    ForEachTensor(*state.deformation, [&](const std::vector<float>& v) { h.Add(v); });
  }
  return h.Finish().a;
}

Status DataParallel::ReadStats(Backend& backend, int kinds, TrainingStats* stats) {
  ATEX_RETURN_IF_ERROR(backend.ReadStats(kinds, stats));
  return AllReduceStats(*comm_, kinds, stats);
}

Status DataParallel::AgreeWithRoot(bool* flag) {
  if (world_size() == 1) return Status::Ok();
  char byte = *flag ? 1 : 0;
  ATEX_RETURN_IF_ERROR(comm_->Broadcast(&byte, 1, 0));
  *flag = byte != 0;
  return Status::Ok();
}

Status DataParallel::BroadcastJson(nlohmann::json* value) {
  if (world_size() == 1) return Status::Ok();
  std::string text = is_root() ? value->dump() : std::string();
  ATEX_RETURN_IF_ERROR(BroadcastString(*comm_, &text, 0));
  if (!is_root()) *value = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (value->is_discarded()) return MakeError(StatusCode::kInternal, "rank ", rank(), ": broadcast JSON is malformed");
  return Status::Ok();
}

Status DataParallel::CheckReplicasAgree(Backend& backend, const std::string& where) {
  if (world_size() == 1) return Status::Ok();
  ModelState state;
  ATEX_RETURN_IF_ERROR(backend.Save(&state));
  // Every rank's checksum, gathered by a sum into its own slots: split into 32-bit halves,
  // which a double holds exactly, so the message can name each drifting rank's value.
  const uint64_t mine = ParameterChecksum(state);
  std::vector<double> halves(2 * static_cast<size_t>(world_size()), 0.0);
  halves[2 * rank()] = static_cast<double>(mine >> 32);
  halves[2 * rank() + 1] = static_cast<double>(mine & 0xffffffffu);
  ATEX_RETURN_IF_ERROR(comm_->AllReduceSum(halves.data(), halves.size()));
  const auto checksum_of = [&](int r) {
    return (static_cast<uint64_t>(halves[2 * r]) << 32) | static_cast<uint64_t>(halves[2 * r + 1]);
  };
  std::string ranks;
  for (int r = 1; r < world_size(); ++r) {
    if (checksum_of(r) == checksum_of(0)) continue;
    ranks += (ranks.empty() ? "" : ", ") + std::to_string(r) + " (checksum " + std::to_string(checksum_of(r)) + ")";
  }
  if (ranks.empty()) return Status::Ok();
  return MakeError(StatusCode::kInternal, "data parallel: at ", where, " the parameters of rank(s) ", ranks,
                   " differ from rank 0's (checksum ", checksum_of(0),
                   "); the replicas drifted apart (a gradient or statistic not reduced, or a non-deterministic ",
                   "update)");
}

}  // namespace atex::train
