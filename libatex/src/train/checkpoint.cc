#include "atex/train/checkpoint.h"

#include <cstring>
#include <filesystem>
#include <unistd.h>

#include "atex/container.h"
#include "atex/file_io.h"
#include "atex/train/trainer.h"

namespace atex::train {
namespace {

constexpr char kMagic[8] = {'A', 'T', 'E', 'X', 'O', 'P', 'T', '1'};

// Every moment array of a state, in the file's order.
template <typename State, typename Fn>
void ForEachMoment(State& s, Fn&& fn) {
  for (auto* g : {&s.m_gaussians, &s.v_gaussians}) {
    fn(g->positions);
    fn(g->rotations);
    fn(g->log_scales);
    fn(g->opacity_logits);
    fn(g->sh);
  }
  fn(s.m_texels);
  fn(s.v_texels);
  for (auto* d : {&s.m_deformation, &s.v_deformation}) {
    if (!d->has_value()) continue;
    auto& field = **d;
    for (auto& scale : field.planes) {
      for (auto& plane : scale) fn(plane);
    }
    for (auto& l : field.trunk) {
      fn(l.weight);
      fn(l.bias);
    }
    for (auto& head : field.heads) {
      for (auto& l : head) {
        fn(l.weight);
        fn(l.bias);
      }
    }
  }
}

}  // namespace

Status WriteCheckpoint(const std::string& dir, const ModelState& state, const Metadata& metadata,
                       const nlohmann::json& trainer) {
  namespace fs = std::filesystem;
  const fs::path target(dir);
  const fs::path staging = target.string() + ".tmp-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(staging, ec);
  fs::create_directories(staging, ec);
  if (ec) return MakeError(StatusCode::kIoError, "checkpoint: cannot create ", staging.string(), ": ", ec.message());

  WriteOptions lossless;  // float32 streams: a resumed run continues bit-exactly
  ATEX_RETURN_IF_ERROR(WriteAssetFile((staging / "model.atex").string(), AssetFromState(state, metadata), lossless));

  std::vector<uint8_t> bytes(kMagic, kMagic + 8);
  ForEachMoment(state, [&](const std::vector<float>& values) {
    const uint64_t count = values.size();
    const size_t at = bytes.size();
    bytes.resize(at + 8 + count * 4);
    std::memcpy(bytes.data() + at, &count, 8);  // the project targets little-endian hosts (format_spec/atex.md)
    std::memcpy(bytes.data() + at + 8, values.data(), count * 4);
  });
  ATEX_RETURN_IF_ERROR(WriteFileAtomic((staging / "optimizer.bin").string(), bytes));
  nlohmann::json json = trainer;
  json["adam_steps"] = state.adam_steps;
  const std::string text = json.dump(2);
  ATEX_RETURN_IF_ERROR(WriteFileAtomic((staging / "trainer.json").string(), text.data(), text.size()));

  // Swap into place: the old checkpoint is removed only once the new one is complete.
  const fs::path old = target.string() + ".old-" + std::to_string(::getpid());
  if (fs::exists(target)) {
    fs::rename(target, old, ec);
    if (ec) return MakeError(StatusCode::kIoError, "checkpoint: cannot move ", target.string(), ": ", ec.message());
  }
  fs::rename(staging, target, ec);
  if (ec)
    return MakeError(StatusCode::kIoError, "checkpoint: cannot rename into ", target.string(), ": ", ec.message());
  fs::remove_all(old, ec);
  return Status::Ok();
}

StatusOr<Checkpoint> ReadCheckpoint(const std::string& dir) {
  namespace fs = std::filesystem;
  const fs::path root(dir);
  Checkpoint cp;
  ATEX_ASSIGN_OR_RETURN(Asset asset, ReadAssetFile((root / "model.atex").string()));
  cp.metadata = asset.metadata;
  cp.state = StateFromAsset(asset);
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> text, ReadFileBytes((root / "trainer.json").string(), 64 << 20));
  cp.trainer = nlohmann::json::parse(text.begin(), text.end(), nullptr, false);
  if (cp.trainer.is_discarded() || !cp.trainer.is_object()) {
    return MakeError(StatusCode::kCorrupt, (root / "trainer.json").string(), ": not a JSON object");
  }
  // The fields the trainer reads back must have their types (json::value() throws otherwise).
  const std::string trainer_path = (root / "trainer.json").string();
  const auto& t = cp.trainer;
  if ((t.contains("phase") && !t["phase"].is_string()) || (t.contains("step") && !t["step"].is_number_integer()) ||
      (t.contains("total_steps") && !t["total_steps"].is_number_integer()) ||
      (t.contains("lr_scale") && !t["lr_scale"].is_number())) {
    return MakeError(StatusCode::kCorrupt, trainer_path, ": phase, step, total_steps or lr_scale has the wrong type");
  }
  if (t.contains("adam_steps")) {
    const auto& steps = t["adam_steps"];
    if (!steps.is_array() || steps.size() != cp.state.adam_steps.size()) {
      return MakeError(StatusCode::kCorrupt, trainer_path, ": adam_steps is not an array of ",
                       cp.state.adam_steps.size(), " integers");
    }
    for (size_t k = 0; k < steps.size(); ++k) {
      if (!steps[k].is_number_integer()) {
        return MakeError(StatusCode::kCorrupt, trainer_path, ": adam_steps[", k, "] is not an integer");
      }
      cp.state.adam_steps[k] = steps[k].get<int64_t>();
    }
  }

  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, ReadFileBytes((root / "optimizer.bin").string()));
  if (bytes.size() < 8 || std::memcmp(bytes.data(), kMagic, 8) != 0) {
    return MakeError(StatusCode::kBadMagic, (root / "optimizer.bin").string(), ": not an atex optimizer file");
  }
  size_t at = 8;
  Status status;
  ForEachMoment(cp.state, [&](std::vector<float>& values) {
    if (!status.ok()) return;
    uint64_t count = 0;
    if (bytes.size() - at < 8) {
      status = MakeError(StatusCode::kTruncated, "optimizer.bin: truncated at byte ", at);
      return;
    }
    std::memcpy(&count, bytes.data() + at, 8);
    at += 8;
    if (count != values.size() || (bytes.size() - at) / 4 < count) {
      status = MakeError(StatusCode::kCorrupt, "optimizer.bin: array of ", count, " values at byte ", at - 8,
                         " where the model needs ", values.size());
      return;
    }
    std::memcpy(values.data(), bytes.data() + at, count * 4);
    at += count * 4;
  });
  ATEX_RETURN_IF_ERROR(status);
  if (at != bytes.size()) {
    return MakeError(StatusCode::kCorrupt, "optimizer.bin: ", bytes.size() - at, " trailing bytes");
  }
  return cp;
}

}  // namespace atex::train
