// The plan's measurements (measure.h).
#include "measure.h"

#include <numeric>

#include "atex/train/trainer.h"
#include "container/chunks.h"
#include "container/fingerprint.h"
#include "cpu_probes.h"

namespace atex::fit::internal {

Measurer::Measurer(ProbeRenderer* renderer, EncodeCache* chunks, MeasureTiming* timing, PruneMeasure prune,
                   bool keep_decoded)
    : renderer_(renderer), chunks_(chunks), timing_(timing), prune_(prune), keep_decoded_(keep_decoded) {
  cpu_ = renderer->cpu_renderer();
  if (cpu_ != nullptr) {
    std::vector<Camera> cameras;
    for (const Probe& p : renderer->probes()) cameras.push_back(p.camera);
    incremental_ = cpu_->Incremental(cameras);
  }
}

Measurer::~Measurer() = default;

StatusOr<Candidate> Measurer::Encode(StateRef state) {
  if (state.write.draco_positions) return EncodeAndDecode(state);  // what the read back does not model
  Stopwatch clock;
  // The file's exact size: its chunks are encoded (unchanged ones come from the cache) but
  // not assembled into a file that nothing reads.
  auto bytes = EncodedAssetSize(state.asset, state.write, chunks_);
  const double encode_seconds = clock.Lap();
  const auto count = [&](double decode_seconds) {
    std::lock_guard<std::mutex> lock(timing_mutex_);
    timing_->encode_seconds += encode_seconds;
    timing_->decode_seconds += decode_seconds;
  };
  if (!bytes.ok()) {
    count(0);
    return bytes.status();
  }
  Candidate c;
  c.measured.bytes = *bytes;
  // What a reader gets, computed from the values (container/read_back.h) rather than decoded
  // from the file: the same bits, without decompressing every stream of every candidate.
  auto decoded = container::DecodedAsWritten(state.asset, state.write, /*read_stats=*/false, &read_back_);
  count(clock.Lap());
  if (!decoded.ok()) return decoded.status();
  c.decoded = std::move(decoded).value();
  return c;
}

StatusOr<Candidate> Measurer::EncodeAndDecode(StateRef state) {
  Stopwatch clock;
  auto file = EncodeAsset(state.asset, state.write, chunks_);
  const double encode_seconds = clock.Lap();
  StatusOr<Asset> decoded = Status(StatusCode::kInternal, "not decoded");
  if (file.ok()) {
    ReadOptions read;
    read.read_stats = false;
    // The bytes were encoded from checked values a moment ago; their CRCs protect nothing here.
    read.verify_checksums = false;
    decoded = DecodeAsset(file->data(), file->size(), read);
  }
  {
    std::lock_guard<std::mutex> lock(timing_mutex_);
    timing_->encode_seconds += encode_seconds;
    timing_->decode_seconds += clock.Lap();
  }
  if (!file.ok()) return file.status();
  if (!decoded.ok()) return decoded.status();
  Candidate c;
  c.measured.bytes = file->size();
  c.decoded = std::move(decoded).value();
  return c;
}

namespace {

train::StateKeys::Key KeyOf(const container::Fingerprint& f) { return {f.a, f.b}; }

train::StateKeys::Key KeyOf(const std::vector<float>& values) {
  return KeyOf(container::BlockFingerprint(values.data(), values.size() * sizeof(float)));
}

// The keys of a render state's value arrays (GPU backends keep those they hold already:
// Backend::LoadKeyed). A candidate changes one or two of them.
train::StateKeys RenderKeys(const train::ModelState& state) {
  const Gaussians& g = state.gaussians;
  train::StateKeys keys;
  keys.positions = KeyOf(g.positions);
  keys.rotations = KeyOf(g.rotations);
  keys.log_scales = KeyOf(g.log_scales);
  keys.opacity = KeyOf(g.opacity_logits);
  container::FingerprintBuilder sh;
  sh.AddValue(int32_t{g.sh_degree}).AddValue(container::BlockFingerprint(g.sh.data(), g.sh.size() * sizeof(float)));
  keys.sh = KeyOf(sh.Finish());
  keys.time_windows = KeyOf(g.time_windows);
  if (state.textures) {
    const TexturePool& t = *state.textures;
    container::FingerprintBuilder texels;
    texels.Add(t.heights).Add(t.widths).Add(t.axis_u).Add(t.axis_v);
    texels.AddValue(container::BlockFingerprint(t.texels.data(), t.texels.size() * sizeof(float)));
    keys.texels = KeyOf(texels.Finish());
  }
  if (state.deformation) {
    const DeformationField& d = *state.deformation;
    container::FingerprintBuilder field;
    field.Add(container::EncodeDeformationConfig(d.config));
    for (const auto& scale : d.planes)
      for (const std::vector<float>& plane : scale) field.Add(plane);
    const auto add_linear = [&](const Linear& l) { field.AddValue(l.in).AddValue(l.out).Add(l.weight).Add(l.bias); };
    for (const Linear& l : d.trunk) add_linear(l);
    for (const auto& head : d.heads)
      for (const Linear& l : head) add_linear(l);
    keys.deformation = KeyOf(field.Finish());
  }
  return keys;
}

}  // namespace

StatusOr<double> Measurer::Distortion(const Candidate& candidate, const CandidateMap& map,
                                      std::shared_ptr<const IncrementalProbes::Pending>* pending) {
  Stopwatch clock;
  StatusOr<std::vector<Image>> renders = [&]() -> StatusOr<std::vector<Image>> {
    if (incremental_) return incremental_->Render(candidate.decoded, map, pending);
    if (candidate.render_state) {
      return renderer_->RenderState(*candidate.render_state, candidate.request, &candidate.render_keys);
    }
    return renderer_->Render(candidate.decoded);
  }();
  if (!renders.ok()) return renders.status();
  timing_->render_seconds += clock.Lap();
  ATEX_ASSIGN_OR_RETURN(double mse, MeanSquaredError(*renders, reference_));
  timing_->distortion_seconds += clock.Lap();
  return mse;
}

StatusOr<Measured> Measurer::Start(const Asset& input, const State& initial) {
  Stopwatch clock;
  if (incremental_) {
    // The input is the first base; its images are the reference. When the importance was
    // just measured on the same Gaussians, that render is the base already: nothing changes.
    const size_t n = input.gaussians.size();
    CandidateMap all;
    const Asset* measured = cpu_->ImportanceBase();
    if (measured != nullptr && measured->gaussians.size() == n) {
      all.base_of.resize(n);
      std::iota(all.base_of.begin(), all.base_of.end(), 0u);
      all.changed = ChangedGaussians(*measured, input, all.base_of);
    } else {
      all.base_of.assign(n, kNoBase);
      all.changed.resize(n);
      std::iota(all.changed.begin(), all.changed.end(), 0u);
    }
    std::shared_ptr<const IncrementalProbes::Pending> pending;
    ATEX_ASSIGN_OR_RETURN(reference_, incremental_->Render(input, all, &pending));
    ATEX_RETURN_IF_ERROR(incremental_->Commit(*pending));
    current_ = input;
    current_kept_.resize(input.gaussians.size());
    std::iota(current_kept_.begin(), current_kept_.end(), 0u);
  } else {
    ATEX_ASSIGN_OR_RETURN(reference_, renderer_->Render(input));
  }
  timing_->reference_seconds += clock.Lap();
  ++timing_->measurements;
  ATEX_ASSIGN_OR_RETURN(Candidate c, Encode(initial));
  if (incremental_) {
    c.map.base_of = BaseIndices(current_kept_, initial.kept);
    c.map.changed = ChangedGaussians(current_, c.decoded, c.map.base_of);
  }
  ATEX_ASSIGN_OR_RETURN(c.measured.distortion, Distortion(c, c.map, &c.pending));
  return Take(initial, c);
}

StatusOr<Candidate> Measurer::Prepare(StateRef next, const Move& move) {
  ATEX_ASSIGN_OR_RETURN(Candidate c, Encode(next));
  if (!incremental_) {
    Stopwatch clock;
    c.request = train::RenderRequestFor(c.decoded);
    if (keep_decoded_) {
      c.render_state = std::make_shared<const train::ModelState>(train::RenderStateFromAsset(c.decoded));
    } else {
      // Nothing reads the decode after the render: its arrays become the render state.
      auto state = std::make_shared<train::ModelState>();
      state->gaussians = std::move(c.decoded.gaussians);
      state->textures = std::move(c.decoded.textures);
      state->deformation = std::move(c.decoded.deformation);
      c.decoded.gaussians = Gaussians();
      c.decoded.textures.reset();
      c.decoded.deformation.reset();
      c.render_state = std::move(state);
    }
    c.render_keys = RenderKeys(*c.render_state);
    const double seconds = clock.Lap();
    std::lock_guard<std::mutex> lock(timing_mutex_);
    timing_->render_state_seconds += seconds;
  } else {
    c.map.base_of = BaseIndices(current_kept_, next.kept);
    c.range_stable = prune_ != PruneMeasure::kExact && move.lever == Lever::kPrune;
    if (!c.range_stable) c.map.changed = ChangedGaussians(current_, c.decoded, c.map.base_of);
  }
  return c;
}

Status Measurer::Score(Candidate* c) {
  ATEX_ASSIGN_OR_RETURN(c->measured.distortion, Distortion(*c, c->map, &c->pending));
  c->render_state.reset();  // rendered: its memory is a whole asset's
  return Status::Ok();
}

StatusOr<Candidate> Measurer::Measure(StateRef next, const Move& move) {
  ATEX_ASSIGN_OR_RETURN(Candidate c, Prepare(next, move));
  ATEX_RETURN_IF_ERROR(Score(&c));
  return c;
}

StatusOr<Measured> Measurer::Take(StateRef next, const Candidate& candidate) {
  Measured measured = candidate.measured;
  if (!incremental_) return measured;
  std::shared_ptr<const IncrementalProbes::Pending> pending = candidate.pending;
  if (candidate.range_stable && prune_ == PruneMeasure::kRangeStableConfirmed) {
    // Confirm: the exact decode, its requantised survivors included.
    CandidateMap exact = candidate.map;
    exact.changed = ChangedGaussians(current_, candidate.decoded, exact.base_of);
    ++timing_->measurements;  // alone: no Prepare runs during Take
    ATEX_ASSIGN_OR_RETURN(measured.distortion, Distortion(candidate, exact, &pending));
  }
  ATEX_RETURN_IF_ERROR(incremental_->Commit(*pending));
  current_ = candidate.decoded;
  current_kept_ = next.kept;
  return measured;
}

}  // namespace atex::fit::internal
