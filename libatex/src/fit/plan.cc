// The fitter's plan: greedy rate–distortion search over the levers (fit.h), and
// applying a plan to a budget.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <tuple>

#include "atex/fit.h"
#include "levers.h"
#include "texture_shrink.h"

namespace atex::fit {

const char* LeverName(Lever lever) {
  switch (lever) {
    case Lever::kPrune: return "prune";
    case Lever::kTextures: return "textures";
    case Lever::kShDegree: return "sh";
    case Lever::kEncoding: return "encoding";
    case Lever::kGrid: return "grid";
    case Lever::kAllTextures: return "all-textures";
  }
  return "unknown";
}

namespace {
constexpr Lever kLevers[] = {Lever::kPrune, Lever::kTextures, Lever::kShDegree,
                             Lever::kEncoding, Lever::kGrid, Lever::kAllTextures};
}  // namespace

StatusOr<LeverSet> ParseLevers(const std::string& text) {
  if (text == "default") return kDefaultLevers;
  LeverSet set = 0;
  for (size_t start = 0; start <= text.size();) {
    const size_t comma = std::min(text.find(',', start), text.size());
    const std::string name = text.substr(start, comma - start);
    start = comma + 1;
    if (name.empty()) continue;
    bool known = false;
    for (Lever lever : kLevers) {
      if (name == LeverName(lever)) {
        set |= LeverBit(lever);
        known = true;
      }
    }
    if (!known) {
      return MakeError(StatusCode::kInvalidArgument, "unknown lever '", name, "' (known: ",
                       LeverSetNames(kAllLevers), ", or default)");
    }
  }
  if (set == 0) return MakeError(StatusCode::kInvalidArgument, "no lever named in '", text, "'");
  return set;
}

std::string LeverSetNames(LeverSet set) {
  std::string names;
  for (Lever lever : kLevers) {
    if (!HasLever(set, lever)) continue;
    if (!names.empty()) names += ",";
    names += LeverName(lever);
  }
  return names;
}

const char* StreamName(Stream stream) {
  switch (stream) {
    case Stream::kPositions: return "positions";
    case Stream::kRotations: return "rotations";
    case Stream::kLogScales: return "log_scales";
    case Stream::kOpacities: return "opacities";
    case Stream::kShDc: return "sh_dc";
    case Stream::kShRest: return "sh_rest";
    case Stream::kTexels: return "texels";
    case Stream::kDeformationGrids: return "deformation_grids";
    case Stream::kCount: break;
  }
  return "unknown";
}

namespace {
ScalarEncoding* EncodingField(WriteOptions* o, Stream stream) {
  switch (stream) {
    case Stream::kPositions: return &o->positions;
    case Stream::kRotations: return &o->rotations;
    case Stream::kLogScales: return &o->log_scales;
    case Stream::kOpacities: return &o->opacities;
    case Stream::kShDc: return &o->sh_dc;
    case Stream::kShRest: return &o->sh_rest;
    case Stream::kTexels: return &o->texels;
    default: return &o->deformation_grids;
  }
}
}  // namespace

ScalarEncoding GetEncoding(const WriteOptions& options, Stream stream) {
  WriteOptions copy = options;
  return *EncodingField(&copy, stream);
}
void SetEncoding(WriteOptions* options, Stream stream, ScalarEncoding encoding) {
  *EncodingField(options, stream) = encoding;
}

std::string DescribeMove(const Move& m) {
  switch (m.lever) {
    case Lever::kPrune: return StrCat("prune ", m.count, " Gaussians");
    case Lever::kTextures: return StrCat("shrink ", m.count, " texture axes");
    case Lever::kShDegree: return "lower the SH degree by one";
    case Lever::kEncoding: return StrCat("store ", StreamName(m.stream), " as ", ScalarEncodingName(m.encoding));
    case Lever::kGrid: return "halve the deformation grid resolution";
    case Lever::kAllTextures: return "halve the longer axis of every texture";
  }
  return "unknown move";
}

nlohmann::json TimingToJson(const MeasureTiming& t) {
  const double per = t.measurements > 0 ? 1.0 / t.measurements : 0.0;
  const double parts = t.apply_seconds + t.encode_seconds + t.decode_seconds + t.render_seconds +
                       t.distortion_seconds + t.reference_seconds + t.propose_seconds;
  return {{"measurements", t.measurements},
          {"seconds", {{"apply", t.apply_seconds}, {"encode", t.encode_seconds}, {"decode", t.decode_seconds},
                       {"render", t.render_seconds}, {"distortion", t.distortion_seconds},
                       {"reference", t.reference_seconds}, {"propose", t.propose_seconds},
                       {"other", std::max(0.0, t.total_seconds - parts)}, {"total", t.total_seconds}}},
          {"seconds_per_measurement",
           {{"apply", t.apply_seconds * per}, {"encode", t.encode_seconds * per}, {"decode", t.decode_seconds * per},
            {"render", t.render_seconds * per}, {"distortion", t.distortion_seconds * per}}}};
}

nlohmann::json MoveToJson(const Move& m) {
  nlohmann::json j = {{"lever", LeverName(m.lever)},
                      {"what", DescribeMove(m)},
                      {"bytes_after", m.bytes_after},
                      {"distortion_after", m.distortion_after},
                      {"proxy_psnr_after", m.distortion_after > 0 ? -10.0 * std::log10(m.distortion_after) : 99.0}};
  if (m.divisible()) j["count"] = m.count;
  if (m.lever == Lever::kEncoding) {
    j["stream"] = StreamName(m.stream);
    j["encoding"] = ScalarEncodingName(m.encoding);
  }
  return j;
}

nlohmann::json ComponentsToJson(const std::vector<uint8_t>& encoded) {
  nlohmann::json j = nlohmann::json::object();
  auto info = InspectContainer(encoded.data(), encoded.size());
  if (!info.ok()) return j;
  for (const ComponentSize& c : ComponentBytes(*info)) j[c.component] = c.bytes;
  return j;
}

StatusOr<WriteOptions> EncodingsOfFile(const uint8_t* data, size_t size, const WriteOptions& base) {
  ATEX_ASSIGN_OR_RETURN(ContainerInfo info, InspectContainer(data, size));
  WriteOptions out = base;
  static const std::map<std::string, Stream> kStreams = {
      {"GPOS", Stream::kPositions}, {"GROT", Stream::kRotations}, {"GSCL", Stream::kLogScales},
      {"GOPA", Stream::kOpacities}, {"GSH0", Stream::kShDc},      {"GSHR", Stream::kShRest},
      {"TEXL", Stream::kTexels},    {"DGRD", Stream::kDeformationGrids}};
  for (const ChunkInfo& chunk : info.chunks) {
    const auto it = kStreams.find(chunk.type);
    if (it == kStreams.end()) continue;
    if (chunk.codec == Codec::kDraco) continue;  // Draco positions: re-encoded with `base`'s settings
    ATEX_ASSIGN_OR_RETURN(ScalarEncoding e, StreamEncodingOf(data, size, chunk));
    SetEncoding(&out, it->second, e);
  }
  return out;
}

Status ApplyMove(const Move& move, const std::vector<uint32_t>& prune_order, Asset* asset, WriteOptions* write,
                 std::vector<uint32_t>* kept, int min_grid_resolution) {
  switch (move.lever) {
    case Lever::kPrune: {
      const size_t n = asset->gaussians.size();
      if (kept->size() != n) return MakeError(StatusCode::kInternal, "fit: kept list out of step with the asset");
      if (move.count >= n) {
        return MakeError(StatusCode::kInvalidArgument, "fit: cannot prune ", move.count, " of ", n, " Gaussians");
      }
      std::vector<uint8_t> keep(n, 1);
      uint64_t removed = 0;
      for (uint32_t input_index : prune_order) {
        if (removed == move.count) break;
        const auto it = std::lower_bound(kept->begin(), kept->end(), input_index);
        if (it == kept->end() || *it != input_index) continue;  // already gone
        const size_t current = static_cast<size_t>(it - kept->begin());
        if (keep[current]) {
          keep[current] = 0;
          ++removed;
        }
      }
      *asset = SubsetGaussians(*asset, keep);
      std::vector<uint32_t> still;
      still.reserve(n - removed);
      for (size_t i = 0; i < n; ++i)
        if (keep[i]) still.push_back((*kept)[i]);
      *kept = std::move(still);
      return Status::Ok();
    }
    case Lever::kTextures:
      return ShrinkTextures(asset, move.count).status();
    case Lever::kShDegree:
      return LowerShDegree(asset);
    case Lever::kEncoding:
      SetEncoding(write, move.stream, move.encoding);
      return Status::Ok();
    case Lever::kGrid:
      return CoarsenGrid(asset, min_grid_resolution);
    case Lever::kAllTextures:
      return HalveAllTextures(asset);
  }
  return MakeError(StatusCode::kInternal, "fit: unknown lever");
}

StatusOr<Asset> KeepMostImportant(const Asset& asset, const std::vector<uint32_t>& order, double fraction,
                                  std::vector<uint32_t>* kept) {
  const size_t n = asset.gaussians.size();
  if (!(fraction > 0.0 && fraction <= 1.0)) {
    return MakeError(StatusCode::kInvalidArgument, "keep-count fraction ", fraction, " is not in (0, 1]");
  }
  if (order.size() != n) {
    return MakeError(StatusCode::kInvalidArgument, "importance order has ", order.size(), " entries for ", n,
                     " Gaussians (the --order-from asset must have the same Gaussians)");
  }
  std::vector<uint8_t> seen(n, 0);
  for (uint32_t i : order) {
    if (i >= n || seen[i]) return MakeError(StatusCode::kInvalidArgument, "importance order is not a permutation");
    seen[i] = 1;
  }
  const size_t keep_count = std::clamp<size_t>(static_cast<size_t>(std::ceil(fraction * n - 1e-9)), 1, n);
  std::vector<uint8_t> keep(n, 0);
  for (size_t k = n - keep_count; k < n; ++k) keep[order[k]] = 1;  // the most important are last
  if (kept != nullptr) {
    kept->clear();
    for (size_t i = 0; i < n; ++i)
      if (keep[i]) kept->push_back(static_cast<uint32_t>(i));
  }
  return SubsetGaussians(asset, keep);
}

StatusOr<uint64_t> MinimumBytes(const Asset& asset, const WriteOptions& write, int min_grid_resolution,
                                LeverSet levers) {
  Asset smallest = asset;
  if (HasLever(levers, Lever::kPrune) && asset.gaussians.size() > 1) {
    const std::vector<uint32_t> order = ImportanceOrder(asset, 0);
    ATEX_ASSIGN_OR_RETURN(smallest, KeepMostImportant(asset, order, 1.0 / static_cast<double>(asset.gaussians.size())));
  }
  if (HasLever(levers, Lever::kShDegree)) {
    while (smallest.gaussians.sh_degree > 0) ATEX_RETURN_IF_ERROR(LowerShDegree(&smallest));
  }
  if (HasLever(levers, Lever::kTextures)) {
    ATEX_RETURN_IF_ERROR(ShrinkTextures(&smallest, std::numeric_limits<uint64_t>::max()).status());
  } else if (HasLever(levers, Lever::kAllTextures)) {  // the same 1×1 pool, its texture_mode kept
    while (smallest.textures && ShrinkableTexels(*smallest.textures) > 0) {
      ATEX_RETURN_IF_ERROR(HalveAllTextures(&smallest));
    }
  }
  if (HasLever(levers, Lever::kGrid)) {
    while (CanCoarsenGrid(smallest, min_grid_resolution)) {
      ATEX_RETURN_IF_ERROR(CoarsenGrid(&smallest, min_grid_resolution));
    }
  }
  WriteOptions w = write;
  if (HasLever(levers, Lever::kEncoding)) {
    for (int s = 0; s < static_cast<int>(Stream::kCount); ++s) {
      SetEncoding(&w, static_cast<Stream>(s), ScalarEncoding::kQuant8);
    }
  }
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeAsset(smallest, w));
  return static_cast<uint64_t>(bytes.size());
}

Status CheckBudget(const Asset& asset, const WriteOptions& write, uint64_t budget_bytes, int min_grid_resolution,
                   LeverSet levers) {
  ATEX_ASSIGN_OR_RETURN(uint64_t minimum, MinimumBytes(asset, write, min_grid_resolution, levers));
  if (budget_bytes < minimum) {
    return MakeError(StatusCode::kBudgetTooSmall, "budget of ", budget_bytes,
                     " bytes is below the smallest valid asset that the levers ", LeverSetNames(levers),
                     " can reach from this input, ", minimum,
                     " bytes (prune: one Gaussian; sh: degree 0; textures: 1x1; encoding: every stream q8;"
                     " grid: minimum resolution)");
  }
  return Status::Ok();
}

namespace {

// Seconds since construction or the previous Lap.
class Stopwatch {
 public:
  double Lap() {
    const auto now = std::chrono::steady_clock::now();
    const double seconds = std::chrono::duration<double>(now - last_).count();
    last_ = now;
    return seconds;
  }

 private:
  std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

struct State {
  Asset asset;
  WriteOptions write;
  std::vector<uint32_t> kept;
};

struct Measured {
  uint64_t bytes = 0;
  double distortion = 0;
};

// Encodes (exact bytes; unchanged chunks come from the cache), decodes (exact stored
// values) and renders the probes.
StatusOr<Measured> Measure(const State& state, ProbeRenderer* renderer, const std::vector<Image>& reference,
                           EncodeCache* cache, MeasureTiming* timing, Asset* decoded_out = nullptr) {
  ++timing->measurements;
  Stopwatch clock;
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, EncodeAsset(state.asset, state.write, cache));
  timing->encode_seconds += clock.Lap();
  ReadOptions read;
  read.read_stats = false;
  ATEX_ASSIGN_OR_RETURN(Asset decoded, DecodeAsset(bytes.data(), bytes.size(), read));
  timing->decode_seconds += clock.Lap();
  ATEX_ASSIGN_OR_RETURN(std::vector<Image> renders, renderer->Render(decoded));
  timing->render_seconds += clock.Lap();
  ATEX_ASSIGN_OR_RETURN(double mse, MeanSquaredError(renders, reference));
  timing->distortion_seconds += clock.Lap();
  if (decoded_out != nullptr) *decoded_out = std::move(decoded);
  return Measured{bytes.size(), mse};
}

// The next move of every lever at `state` (prune and texture counts sized to the state).
std::vector<Move> Proposals(const State& state, const PlanOptions& o) {
  std::vector<Move> moves;
  const Asset& a = state.asset;
  const size_t n = a.gaussians.size();
  const auto allowed = [&](Lever lever) { return HasLever(o.levers, lever); };
  if (allowed(Lever::kPrune) && n > 1) {
    Move m;
    m.lever = Lever::kPrune;
    m.count = std::clamp<uint64_t>(static_cast<uint64_t>(o.prune_fraction * n), 1, n - 1);
    moves.push_back(m);
  }
  if (allowed(Lever::kAllTextures) && a.textures && ShrinkableTexels(*a.textures) > 0) {
    Move m;
    m.lever = Lever::kAllTextures;
    moves.push_back(m);
  }
  if (allowed(Lever::kTextures) && a.textures && ShrinkableTexels(*a.textures) > 0) {
    uint64_t growable = 0;
    for (size_t i = 0; i < a.textures->size(); ++i) growable += a.textures->heights[i] * a.textures->widths[i] > 1;
    Move m;
    m.lever = Lever::kTextures;
    m.count = std::max<uint64_t>(1, static_cast<uint64_t>(o.texture_fraction * static_cast<double>(growable)));
    moves.push_back(m);
  }
  if (allowed(Lever::kShDegree) && a.gaussians.sh_degree > 0) {
    Move m;
    m.lever = Lever::kShDegree;
    moves.push_back(m);
  }
  for (int s = 0; allowed(Lever::kEncoding) && s < static_cast<int>(Stream::kCount); ++s) {
    const auto stream = static_cast<Stream>(s);
    if (stream == Stream::kShRest && a.gaussians.sh_degree == 0) continue;
    if (stream == Stream::kTexels && !a.textures) continue;
    if (stream == Stream::kDeformationGrids && !a.deformation) continue;
    const ScalarEncoding current = GetEncoding(state.write, stream);
    std::vector<ScalarEncoding> next;
    if (current == ScalarEncoding::kFloat32) next = {ScalarEncoding::kFloat16, ScalarEncoding::kQuant16};
    if (current == ScalarEncoding::kFloat16 || current == ScalarEncoding::kQuant16) next = {ScalarEncoding::kQuant8};
    for (ScalarEncoding e : next) {
      Move m;
      m.lever = Lever::kEncoding;
      m.stream = stream;
      m.encoding = e;
      moves.push_back(m);
    }
  }
  if (allowed(Lever::kGrid) && CanCoarsenGrid(a, o.min_grid_resolution)) {
    Move m;
    m.lever = Lever::kGrid;
    moves.push_back(m);
  }
  return moves;
}

// Identity of a proposal across states (counts change with the state, the kind does not).
using MoveKey = std::tuple<int, int, int>;
MoveKey KeyOf(const Move& m) {
  return {static_cast<int>(m.lever), m.lever == Lever::kEncoding ? static_cast<int>(m.stream) : -1,
          m.lever == Lever::kEncoding ? static_cast<int>(m.encoding) : -1};
}

}  // namespace

StatusOr<Plan> BuildPlan(const Asset& asset, ProbeRenderer* renderer, const PlanOptions& options) {
  if (!(options.prune_fraction > 0 && options.prune_fraction < 1) ||
      !(options.texture_fraction > 0 && options.texture_fraction <= 1)) {
    return MakeError(StatusCode::kInvalidArgument, "fit: step fractions must be in (0, 1)");
  }
  if ((options.levers & ~kAllLevers) != 0 || options.levers == 0) {
    return MakeError(StatusCode::kInvalidArgument, "fit: the lever set ", options.levers,
                     " names no lever or an unknown one");
  }
  ATEX_RETURN_IF_ERROR(ValidateAsset(asset));
  Plan plan;
  Stopwatch whole;
  plan.prune_order = ImportanceOrder(asset, options.seed);
  // Reference: the untrimmed asset exactly as given (before any re-encoding).
  Stopwatch reference_clock;
  ATEX_ASSIGN_OR_RETURN(std::vector<Image> reference, renderer->Render(asset));
  plan.timing.reference_seconds = reference_clock.Lap();

  State state{asset, options.write, {}};
  state.kept.resize(asset.gaussians.size());
  std::iota(state.kept.begin(), state.kept.end(), 0u);
  // Most candidates change one or two chunks of the current state; the others are
  // compressed once, not once per candidate.
  EncodeCache chunks;
  ATEX_ASSIGN_OR_RETURN(Measured current, Measure(state, renderer, reference, &chunks, &plan.timing));
  plan.initial_bytes = current.bytes;
  plan.initial_distortion = current.distortion;

  // Lazy greedy: each proposal keeps the cost per byte measured at an earlier state
  // (costs change slowly between moves); a stale best is measured again, and a move is
  // taken only when the best cost is a fresh one (measured at the current state).
  struct Cached {
    double ratio = 0;
    uint64_t saving = 0;
    bool fresh = false;
  };
  constexpr double kNoGain = std::numeric_limits<double>::infinity();
  struct Evaluated {
    Cached cost;
    Measured measured;
    State next;     // the state after the move (kept only for the best fresh evaluation)
    Asset decoded;  // what a reader of `next` gets (for accept_more)
  };
  const auto better = [](const Cached& a, const Cached& b) {
    return a.ratio < b.ratio || (a.ratio == b.ratio && a.saving > b.saving);
  };
  const auto evaluate = [&](const Move& proposal) -> StatusOr<Evaluated> {
    Evaluated e;
    e.cost = Cached{kNoGain, 0, true};
    Stopwatch clock;
    e.next = state;
    const Status applied = ApplyMove(proposal, plan.prune_order, &e.next.asset, &e.next.write, &e.next.kept,
                                     options.min_grid_resolution);
    plan.timing.apply_seconds += clock.Lap();
    if (!applied.ok()) return e;  // a move the state cannot take (e.g. nothing left to halve) is not a move
    auto measured = Measure(e.next, renderer, reference, &chunks, &plan.timing, &e.decoded);
    if (!measured.ok()) {
      // A stream that an encoding cannot hold (f16 overflow) is simply not a move.
      if (measured.status().code() == StatusCode::kOutOfRange) return e;
      return measured.status();
    }
    e.measured = *measured;
    if (measured->bytes >= current.bytes) return e;
    const uint64_t saving = current.bytes - measured->bytes;
    const double damage = std::max(0.0, measured->distortion - current.distortion);
    e.cost = Cached{damage / static_cast<double>(saving), saving, true};
    return e;
  };

  std::map<MoveKey, Cached> cache;
  while (current.bytes > options.floor_bytes) {
    Stopwatch propose_clock;
    const std::vector<Move> proposals = Proposals(state, options);
    plan.timing.propose_seconds += propose_clock.Lap();
    if (proposals.empty()) break;
    // The best evaluation made at the current state, with its state and decoded asset.
    std::optional<std::pair<MoveKey, Evaluated>> best_fresh;
    const auto remember = [&](const Move& p, Evaluated e) {
      cache[KeyOf(p)] = e.cost;
      if (e.cost.ratio != kNoGain && (!best_fresh || better(e.cost, best_fresh->second.cost))) {
        best_fresh.emplace(KeyOf(p), std::move(e));
      }
    };
    for (const Move& p : proposals) {
      if (cache.count(KeyOf(p)) == 0) {
        ATEX_ASSIGN_OR_RETURN(Evaluated e, evaluate(p));
        remember(p, std::move(e));
      }
    }
    // Each pass either takes a fresh best or refreshes a stale one, so proposals.size() + 1
    // passes always suffice.
    const Move* chosen = nullptr;
    for (size_t pass = 0; pass <= proposals.size() && chosen == nullptr; ++pass) {
      const Move* best = nullptr;
      for (const Move& p : proposals) {
        if (best == nullptr || better(cache[KeyOf(p)], cache[KeyOf(*best)])) best = &p;
      }
      const Cached& cost = cache[KeyOf(*best)];
      if (cost.ratio == kNoGain) break;
      if (cost.fresh && best_fresh && best_fresh->first == KeyOf(*best)) {
        chosen = best;
      } else {
        ATEX_ASSIGN_OR_RETURN(Evaluated e, evaluate(*best));
        remember(*best, std::move(e));
      }
    }
    if (chosen == nullptr) break;  // no lever saves bytes any more
    Evaluated& taken = best_fresh->second;
    Move move = *chosen;
    move.bytes_after = taken.measured.bytes;
    move.distortion_after = taken.measured.distortion;
    if (options.accept_more) {
      ATEX_ASSIGN_OR_RETURN(bool more, options.accept_more(taken.decoded, move));
      if (!more) break;
    }
    state = std::move(taken.next);
    current = taken.measured;
    plan.moves.push_back(move);
    for (auto& entry : cache) entry.second.fresh = false;
    cache.erase(KeyOf(move));  // its next step is a different move (new count, new encoding)
    if (move.lever == Lever::kEncoding) {
      // Both 16-bit options of a stream are decided once one is taken.
      for (ScalarEncoding e : {ScalarEncoding::kFloat16, ScalarEncoding::kQuant16, ScalarEncoding::kQuant8}) {
        cache.erase(MoveKey{static_cast<int>(Lever::kEncoding), static_cast<int>(move.stream), static_cast<int>(e)});
      }
    }
    if (options.progress) {
      options.progress(FitProgress{static_cast<int>(plan.moves.size()), current.bytes, options.floor_bytes,
                                   StrCat(DescribeMove(move), ": ", current.bytes, " bytes, proxy PSNR ",
                                          current.distortion > 0 ? -10.0 * std::log10(current.distortion) : 99.0)});
    }
  }
  plan.timing.total_seconds = whole.Lap();
  return plan;
}

namespace {

// The state after moves[begin, end) applied to `start`; moves[k] (if in range) with its count
// replaced by `count_k` (0: skipped).
StatusOr<State> ApplyRange(State start, const Plan& plan, const std::vector<Move>& moves, size_t begin, size_t end,
                           size_t k, uint64_t count_k) {
  for (size_t i = begin; i < end; ++i) {
    Move m = moves[i];
    if (i == k) {
      if (count_k == 0) continue;
      m.count = count_k;
    }
    ATEX_RETURN_IF_ERROR(ApplyMove(m, plan.prune_order, &start.asset, &start.write, &start.kept));
  }
  return start;
}

State InitialState(const Asset& asset, const WriteOptions& write) {
  State s{asset, write, {}};
  s.kept.resize(asset.gaussians.size());
  std::iota(s.kept.begin(), s.kept.end(), 0u);
  return s;
}

// A replayed state that fits the budget: the count it gives the bisected move, the state and
// its encoded bytes.
struct Refill {
  uint64_t count = 0;
  State state;
  std::vector<uint8_t> bytes;
};

// The states after moves[0, k) for the descending k of RefillSlack, each built from a
// checkpoint up to kStride moves earlier instead of from the input: replaying a whole plan
// of 78 moves on a 140 MB asset takes ~13 s (0.17 s per move applied, measured on the
// Panoptic uniform fit), and the refill needs one prefix per move it tries. Valid while the
// moves before the checkpoint stay as they are (RefillSlack only changes or removes the
// move it tries, at or after the checkpoint).
class PrefixStates {
 public:
  PrefixStates(const Asset& asset, const WriteOptions& write, const Plan& plan)
      : asset_(asset), write_(write), plan_(plan) {}

  StatusOr<State> Before(const std::vector<Move>& moves, size_t k) {
    if (!checkpoint_ || checkpoint_index_ > k) {
      const size_t index = k > kStride ? k - kStride : 0;
      ATEX_ASSIGN_OR_RETURN(State at, ApplyRange(InitialState(asset_, write_), plan_, moves, 0, index, moves.size(), 0));
      checkpoint_ = std::move(at);
      checkpoint_index_ = index;
    }
    return ApplyRange(*checkpoint_, plan_, moves, checkpoint_index_, k, moves.size(), 0);
  }

 private:
  static constexpr size_t kStride = 8;
  const Asset& asset_;
  const WriteOptions& write_;
  const Plan& plan_;
  std::optional<State> checkpoint_;
  size_t checkpoint_index_ = 0;
};

// The smallest count of moves[k] (the other moves as they are) whose output fits `budget`:
// 0 if that fits, else found by bisection on [1, count); the recorded count is known to
// fit. nullopt when no smaller count fits (the whole move is needed). `prefix` is the state
// after moves[0, k), applied once, not once per trial: a texture move on a large asset
// takes most of a second to apply.
StatusOr<std::optional<Refill>> SmallestFittingCount(const State& prefix, const Plan& plan,
                                                     const std::vector<Move>& moves, size_t k, uint64_t budget,
                                                     EncodeCache* cache) {
  // With a large slack the move is usually undone entirely: one trial instead of a bisection.
  ATEX_ASSIGN_OR_RETURN(State without, ApplyRange(prefix, plan, moves, k, moves.size(), k, 0));
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> without_bytes, EncodeAsset(without.asset, without.write, cache));
  if (without_bytes.size() <= budget) {
    return std::optional<Refill>(Refill{0, std::move(without), std::move(without_bytes)});
  }
  uint64_t lo = 1, hi = moves[k].count;
  std::optional<Refill> best;
  while (lo < hi) {
    const uint64_t mid = lo + (hi - lo) / 2;
    ATEX_ASSIGN_OR_RETURN(State trial, ApplyRange(prefix, plan, moves, k, moves.size(), k, mid));
    ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> trial_bytes, EncodeAsset(trial.asset, trial.write, cache));
    if (trial_bytes.size() <= budget) {
      hi = mid;
      best = Refill{mid, std::move(trial), std::move(trial_bytes)};
    } else {
      lo = mid + 1;
    }
  }
  return best;
}

// After an indivisible last move: gives the slack below the budget back by undoing the moves
// before it, latest first (the plan took moves cheapest first, so the latest ones did the
// most damage per byte). A divisible move's count is lowered to the smallest that still
// fits; when even count 0 fits (the move is undone entirely and slack remains), the move is
// dropped and the next earlier move is tried; when it is needed whole, or only partly undone,
// the budget binds there and the refill stops. An indivisible move (an encoding, the SH
// degree, the grid) is undone whole when the output without it still fits and grows, else
// skipped. Every state taken was encoded and fits, so the output stays within the budget.
Status RefillSlack(const Asset& asset, const Plan& plan, const WriteOptions& write, uint64_t budget,
                   std::vector<Move>* moves, State* state, std::vector<uint8_t>* bytes, EncodeCache* cache) {
  std::optional<size_t> earliest_changed;  // index (after any removals) of the earliest move changed
  PrefixStates prefixes(asset, write, plan);
  for (size_t k = moves->size() - 1; k-- > 0;) {  // every move before the last, latest first
    ATEX_ASSIGN_OR_RETURN(State prefix, prefixes.Before(*moves, k));
    if (!(*moves)[k].divisible()) {
      auto trial = ApplyRange(std::move(prefix), plan, *moves, k, moves->size(), k, 0);
      if (!trial.ok()) continue;  // the moves after it do not apply without it: keep it
      auto trial_bytes = EncodeAsset(trial->asset, trial->write, cache);
      if (!trial_bytes.ok() || trial_bytes->size() > budget || trial_bytes->size() <= bytes->size()) continue;
      *state = std::move(*trial);
      *bytes = std::move(*trial_bytes);
      moves->erase(moves->begin() + static_cast<std::ptrdiff_t>(k));
      earliest_changed = k;
      continue;
    }
    ATEX_ASSIGN_OR_RETURN(std::optional<Refill> refill,
                          SmallestFittingCount(prefix, plan, *moves, k, budget, cache));
    if (!refill) break;  // move k is needed whole: the budget binds here
    *state = std::move(refill->state);
    *bytes = std::move(refill->bytes);
    earliest_changed = k;
    if (refill->count > 0) {
      (*moves)[k].count = refill->count;
      break;  // partly undone: the budget binds here
    }
    // Undone entirely and still under budget: drop it and spend the rest on an earlier move.
    moves->erase(moves->begin() + static_cast<std::ptrdiff_t>(k));
  }
  if (!earliest_changed) return Status::Ok();
  // The sizes recorded for the earliest changed move and later ones belong to the plan; measure
  // the real ones. (Their distortion stays the plan's estimate: ApplyPlan does not render.)
  State replay = InitialState(asset, write);
  for (size_t i = 0; i < moves->size(); ++i) {
    ATEX_RETURN_IF_ERROR(ApplyMove((*moves)[i], plan.prune_order, &replay.asset, &replay.write, &replay.kept));
    if (i >= *earliest_changed) {
      ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> step_bytes, EncodeAsset(replay.asset, replay.write, cache));
      (*moves)[i].bytes_after = step_bytes.size();
    }
  }
  return Status::Ok();
}

}  // namespace

StatusOr<Fitted> ApplyPlan(const Asset& asset, const Plan& plan, const WriteOptions& write, uint64_t budget_bytes) {
  Stopwatch whole;
  State state{asset, write, {}};
  state.kept.resize(asset.gaussians.size());
  std::iota(state.kept.begin(), state.kept.end(), 0u);
  Fitted out;
  // The searches below encode many states that differ from each other in a few chunks.
  EncodeCache cache;
  const auto encode = [&cache](const State& s) { return EncodeAsset(s.asset, s.write, &cache); };
  ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> bytes, encode(state));
  if (bytes.size() > budget_bytes) {
    size_t j = 0;
    while (j < plan.moves.size() && plan.moves[j].bytes_after > budget_bytes) ++j;
    if (j == plan.moves.size()) {
      const uint64_t reached = plan.moves.empty() ? bytes.size() : plan.moves.back().bytes_after;
      return MakeError(StatusCode::kOutOfRange, "the fit plan reaches ", reached, " bytes at best, above the budget of ",
                       budget_bytes, " bytes");
    }
    for (size_t k = 0; k < j; ++k) {
      ATEX_RETURN_IF_ERROR(ApplyMove(plan.moves[k], plan.prune_order, &state.asset, &state.write, &state.kept));
      out.moves.push_back(plan.moves[k]);
    }
    Move last = plan.moves[j];
    if (last.divisible() && last.count > 1) {
      // Smallest count that fits (the full count is known to fit).
      uint64_t lo = 1, hi = last.count;
      while (lo < hi) {
        const uint64_t mid = lo + (hi - lo) / 2;
        State trial = state;
        Move m = last;
        m.count = mid;
        ATEX_RETURN_IF_ERROR(ApplyMove(m, plan.prune_order, &trial.asset, &trial.write, &trial.kept));
        ATEX_ASSIGN_OR_RETURN(std::vector<uint8_t> trial_bytes, encode(trial));
        if (trial_bytes.size() <= budget_bytes) {
          hi = mid;
        } else {
          lo = mid + 1;
        }
      }
      last.count = hi;
    }
    ATEX_RETURN_IF_ERROR(ApplyMove(last, plan.prune_order, &state.asset, &state.write, &state.kept));
    ATEX_ASSIGN_OR_RETURN(bytes, encode(state));
    last.bytes_after = bytes.size();
    out.moves.push_back(last);
    if (!last.divisible()) {
      // An indivisible last move (an encoding, the SH degree, the grid) can land far below the
      // budget; give the slack back by undoing moves before it, latest first.
      Stopwatch refill_clock;
      ATEX_RETURN_IF_ERROR(RefillSlack(asset, plan, write, budget_bytes, &out.moves, &state, &bytes, &cache));
      out.refill_seconds = refill_clock.Lap();
    }
  }
  if (bytes.size() > budget_bytes) {
    // Replaying the plan must reproduce its sizes exactly; anything else is a bug, not a fit.
    return MakeError(StatusCode::kInternal, "fit: replaying the plan gave ", bytes.size(),
                     " bytes, above the budget of ", budget_bytes);
  }
  ReadOptions read;
  read.read_stats = false;
  ATEX_ASSIGN_OR_RETURN(out.asset, DecodeAsset(bytes.data(), bytes.size(), read));
  out.bytes = std::move(bytes);
  out.write = state.write;
  out.kept = std::move(state.kept);
  out.apply_seconds = whole.Lap();
  return out;
}

}  // namespace atex::fit
