// Fitting an asset to a byte budget (`atex fit`; docs/fit.md explains the method).
//
// The fitter trims capacity with these levers and spends the budget where it
// matters most:
//   prune         remove the least important Gaussians (accumulated blending weight),
//   textures      shrink textures one axis at a time, least damage per texel first,
//   sh            lower the SH degree of every Gaussian,
//   encoding      store an attribute stream with fewer bits (f32 → f16 / q16 → q8),
//   grid          halve the spatial resolution of the deformation grids,
//   all-textures  halve the longer axis of every texture at once (not used unless
//                 asked for: it never moves texels between Gaussians, so a uniform
//                 pool stays uniform; the paper's fixed-memory protocol, docs/fit.md).
// PlanOptions::levers chooses which ones a plan may use (the first five by default).
// A plan is built greedily: at every step each lever proposes its next move, the
// move is applied, the asset is encoded (exact file bytes) and decoded (exact
// stored values) and rendered from a fixed set of probe views; the move with the
// smallest increase of distortion per byte saved wins. Distortion is the mean
// squared difference to the untrimmed asset's renders of the same probes: the
// dataset's training views when one is given, else orbit views around the scene
// (the documented proxy). On the CPU a candidate is rendered incrementally (only what
// its move changed) and a prune candidate is measured range-stable: the current
// asset less the removed Gaussians, leaving out the re-rounding of the survivors when
// the prune moves a quantised stream's range (src/fit/measure.h; the bytes stay exact).
// The plan is deterministic (the same input, options and
// backend results give the same plan), so one plan serves every budget above its
// floor.
//
// Guarantees: a fitted asset's encoded size is at most the budget (checked on the
// exact bytes, not estimated) and the asset passes ValidateAsset; a budget below
// the smallest valid asset that the plan's levers can reach fails with kBudgetTooSmall
// naming that size (CheckBudget).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/camera.h"
#include "atex/container.h"
#include "atex/image.h"
#include "atex/model.h"
#include "atex/status.h"
#include "atex/train/backend.h"

namespace atex::fit {

enum class Lever : int { kPrune = 0, kTextures = 1, kShDegree = 2, kEncoding = 3, kGrid = 4, kAllTextures = 5 };
const char* LeverName(Lever lever);

// A set of levers: bit (1 << Lever).
using LeverSet = uint32_t;
constexpr LeverSet LeverBit(Lever lever) { return LeverSet{1} << static_cast<int>(lever); }
constexpr bool HasLever(LeverSet set, Lever lever) { return (set & LeverBit(lever)) != 0; }
constexpr LeverSet kDefaultLevers = LeverBit(Lever::kPrune) | LeverBit(Lever::kTextures) |
                                    LeverBit(Lever::kShDegree) | LeverBit(Lever::kEncoding) | LeverBit(Lever::kGrid);
constexpr LeverSet kAllLevers = kDefaultLevers | LeverBit(Lever::kAllTextures);
// "prune,all-textures" → the set; "default" → kDefaultLevers. kInvalidArgument names an
// unknown lever (and lists the known ones) or an empty list.
StatusOr<LeverSet> ParseLevers(const std::string& text);
// The set's lever names, comma-separated, in Lever order.
std::string LeverSetNames(LeverSet set);

// The attribute streams whose encoding the fitter may change (WriteOptions fields).
enum class Stream : int {
  kPositions = 0, kRotations, kLogScales, kOpacities, kShDc, kShRest, kTexels, kDeformationGrids, kCount
};
const char* StreamName(Stream stream);
ScalarEncoding GetEncoding(const WriteOptions& options, Stream stream);
void SetEncoding(WriteOptions* options, Stream stream, ScalarEncoding encoding);

// One move of a plan.
struct Move {
  Lever lever = Lever::kPrune;
  uint64_t count = 0;                 // prune: Gaussians removed; textures: shrink operations (one axis halved each)
                                      // (all-textures is one indivisible step: no count)
  Stream stream = Stream::kPositions;  // encoding: which stream
  ScalarEncoding encoding = ScalarEncoding::kFloat32;  // encoding: its new encoding
  // Measured after the move (cumulative): exact file bytes and probe distortion. In a Fitted,
  // bytes_after is each applied move's own. distortion_after is the plan's, measured at the
  // plan's count, except for a last move ApplyPlan cut to the budget: its distortion is
  // interpolated in the count between the measured states before and after the whole move
  // (an estimate, above the true one where the damage per Gaussian grows along the importance
  // order). After a refill (an indivisible last move) every move keeps the plan's, which is
  // then likely above the output's: the refill undid some of the damage.
  uint64_t bytes_after = 0;
  double distortion_after = 0;        // mean squared error to the untrimmed renders, over probes
  bool divisible() const { return lever == Lever::kPrune || lever == Lever::kTextures; }
};
std::string DescribeMove(const Move& move);

// Views the distortion is measured from, and the reference renders of the untrimmed asset.
struct Probe {
  Camera camera;  // includes the time
};

// Orbit probes around the asset (no dataset): `count` cameras on a sphere around the
// robust centre of the Gaussians (5th–95th percentile box) at 2.5 × its half-diagonal,
// `width`×`height` pixels, 50° vertical field of view, times spread evenly over the
// asset's time range. Deterministic.
std::vector<Probe> OrbitProbes(const Asset& asset, int count, int width, int height);
// Camera re-scaled to at most `max_side` pixels on its longer side (intrinsics scaled).
Camera ScaleCamera(const Camera& camera, int max_side);

namespace internal {
class CpuProbeRenderer;
}

// Renders assets for the fitter's measurements. On a GPU backend, through the backend
// (Load, then one Render per camera). On the CPU backend (or none), through the reference
// rasteriser with the deformation of unchanged positions kept between renders
// (src/fit/cpu_probes.h): a fit renders dozens of nearly equal assets, and deforming
// every Gaussian at every probe time dominated the CPU fit. Equal to the CPU backend's
// renders within the tolerance stated in cpu_probes_test.cc.
class ProbeRenderer {
 public:
  // `backend` may be null (CPU renders).
  ProbeRenderer(train::Backend* backend, std::vector<Probe> probes);
  ~ProbeRenderer();
  const std::vector<Probe>& probes() const { return probes_; }
  // Renders every probe (renders are not clamped; the background is the asset's).
  StatusOr<std::vector<Image>> Render(const Asset& asset);
  // Renders `cameras` and returns one image per camera.
  StatusOr<std::vector<Image>> RenderCameras(const Asset& asset, const std::vector<Camera>& cameras);
  // Renders every probe, as Render, from an asset's render state and request
  // (train::RenderStateFromAsset, train::RenderRequestFor), which a caller can build on
  // another thread beforehand. GPU backends only: kUnsupported on the CPU renderer
  // (cpu_renderer() not null), which renders assets. `keys` (may be null): the content keys of
  // the state's arrays, so that the backend keeps the arrays it holds (Backend::LoadKeyed).
  StatusOr<std::vector<Image>> RenderState(const train::ModelState& state, const train::RenderRequest& request,
                                           const train::StateKeys* keys = nullptr);
  // EnsureImportance over this renderer's probes; on the CPU its deformations stay
  // cached for the plan's renders of the same asset.
  Status EnsureImportance(Asset* asset);
  // The CPU caches' work since construction (all zero on a GPU backend).
  struct CacheCounts {
    uint64_t deformed = 0, deform_reused = 0;   // (Gaussian, probe) deformations computed / reused
    uint64_t tiles_drawn = 0, tiles_reused = 0; // (probe, tile) composited / taken from the cache
  };
  CacheCounts cache_counts() const;
  // Seconds spent loading render states onto the backend (train::Backend::Load) since
  // construction: of a GPU probe render, the upload, not the renders.
  double load_seconds() const { return load_seconds_; }
  // The CPU renderer (null on a GPU backend): the fitter renders its candidates
  // incrementally through it (src/fit/incremental_probes.h).
  internal::CpuProbeRenderer* cpu_renderer() { return cpu_.get(); }

 private:
  StatusOr<std::vector<Image>> RenderOnBackend(const train::ModelState& state, const train::RenderRequest& request,
                                               const std::vector<Camera>& cameras,
                                               const train::StateKeys* keys = nullptr);

  train::Backend* backend_;
  std::vector<Probe> probes_;
  std::unique_ptr<internal::CpuProbeRenderer> cpu_;  // when backend_ is null or the CPU backend
  double load_seconds_ = 0;
};

// Mean over images of the per-pixel, per-channel squared difference (renders clamped to [0, 1]).
StatusOr<double> MeanSquaredError(const std::vector<Image>& a, const std::vector<Image>& b);

struct FitProgress {
  int move = 0;              // moves accepted so far
  uint64_t bytes = 0;        // current exact size
  uint64_t target_bytes = 0; // the floor the plan is built to
  std::string text;          // what happened
};

struct PlanOptions {
  WriteOptions write;              // codec, zstd level and the starting encodings
  uint64_t floor_bytes = 0;        // build moves until the asset is at most this big
  LeverSet levers = kDefaultLevers;  // the levers whose moves are proposed
  double prune_fraction = 0.10;    // a prune move removes this fraction of the current Gaussians (at least 1)
  // A texture move halves, cheapest first, as many axes as this fraction of the textures larger
  // than 1×1 ...
  double texture_fraction = 0.10;
  // ... and at least enough axes to save an estimated this fraction of the bytes
  // the plan sheds (input size less floor_bytes), counted as raw texel bytes. Each move costs a
  // measurement, and where few textures are larger than 1×1 a fraction of them saves almost
  // nothing (tens of bytes of a megabyte). 0: no floor.
  double min_texture_step = 1.0 / 256;
  // A divisible lever (prune, textures) whose moves are taken one after another takes steps
  // this many times larger each time, up to half the Gaussians (prune) or every growable
  // texture (textures); the other divisible lever's move resets it, while a move taken once
  // (encoding, SH degree, grid, all textures) between its steps neither counts nor resets.
  // The plan's last move is cut to the budget by ApplyPlan, so a large step costs no bytes;
  // it makes the greedy search coarser where one lever keeps winning, and needs fewer
  // measurements there. 1: fixed fractions.
  double step_growth = 2.0;
  // Proposals prepared at once (apply, encode and decode; renders stay one at a time), each
  // holding about three copies of the asset in memory: 0 picks min(4, hardware threads), fewer
  // when those copies would not fit in half the RAM; 1 is serial. The plan is the same for any value.
  int parallel_candidates = 0;
  uint64_t seed = 6666;            // breaks importance ties deterministically
  int min_grid_resolution = 4;     // the grid lever stops here (spatial axes)
  std::function<void(const FitProgress&)> progress;
  // Called after each accepted move with the current (trimmed, decoded) asset; return
  // false to stop building (the --quality mode evaluates test PSNR here).
  std::function<StatusOr<bool>(const Asset& decoded, const Move& move)> accept_more;
  // Asked after each accepted move, after `progress`: true stops the plan with kCancelled.
  // Unlike accept_more it keeps no decoded asset per candidate. Null: never.
  std::function<bool()> cancelled;
};

// Where the plan's time went: every measurement of a state (the initial one and each
// candidate move) encodes, decodes and renders the probes. Wall seconds, summed over
// measurements (see overlap_seconds for the ones prepared at once).
struct MeasureTiming {
  int measurements = 0;           // states measured: prepared and scored (or found not encodable)
  // Stale proposals prepared beside a wave in case the lazy greedy refreshes them next
  // (PlanOptions::parallel_candidates > 1), and of those the ones dropped because a move was
  // taken first (their apply, encode and decode seconds are counted above all the same).
  int prepared_ahead = 0, prepared_unused = 0;
  // On a GPU backend, the next steps prepared at a candidate's state before it was taken (its
  // lever's next move), and of those the ones the plan used (the candidate was taken).
  int next_steps_prepared = 0, next_steps_used = 0;
  double apply_seconds = 0;       // applying candidate moves to a copy of the state
  double encode_seconds = 0;      // EncodeAsset (through the chunk cache)
  double decode_seconds = 0;      // DecodeAsset of those bytes
  // On a GPU backend, the decoded candidate's render state (train::RenderStateFromAsset) and
  // its arrays' content keys (Backend::LoadKeyed), built while preparing so that it runs beside
  // other preparations, not before each render.
  double render_state_seconds = 0;
  double render_seconds = 0;      // probe renders: backend load + one render per probe
  double render_load_seconds = 0;  // the backend's loads in the plan's renders (the reference's too; GPU backends)
  double distortion_seconds = 0;  // MeanSquaredError against the reference renders
  double reference_seconds = 0;   // the input's reference renders (once per plan)
  double propose_seconds = 0;     // listing the candidate moves of each state (Proposals)
  // Apply, encode and decode are summed over candidates; those prepared at once
  // (PlanOptions::parallel_candidates) overlap, and this is by how much: their summed
  // preparation seconds less the wall time it took. The parts above less this fit in total.
  double overlap_seconds = 0;
  double total_seconds = 0;       // BuildPlan's whole wall time: the parts above, the prune order,
                                  // bookkeeping and PlanOptions::accept_more (--quality's evaluations)
  ProbeRenderer::CacheCounts probe_cache;  // the CPU probe renderer's reuse during the plan
};
nlohmann::json TimingToJson(const MeasureTiming& timing);

class TextureShrinkMemo;  // the fitter's memo of texture residuals (texture_shrink.h)
namespace internal {
struct PlanTail;  // the plan's last states (plan_state.h)
}

struct Plan {
  MeasureTiming timing;
  uint64_t initial_bytes = 0;
  double initial_distortion = 0;  // of the input re-encoded with the starting encodings (0 for lossless)
  std::vector<Move> moves;
  std::vector<uint32_t> prune_order;  // Gaussians (input indices) in the order prune moves remove them
  // The plan's levers (PlanOptions): ApplyPlan falls back to MinimumBytes's asset with them.
  LeverSet levers = kDefaultLevers;
  int min_grid_resolution = 4;
  // The texture residuals BuildPlan computed (by texture content), for ApplyPlan's replays of
  // the same moves; null: ApplyPlan computes its own. Thread-safe; never changes a result.
  std::shared_ptr<TextureShrinkMemo> texture_memo;
  // The states after the plan's last moves, kept by BuildPlan, so that ApplyPlan given the
  // same asset object and write options starts from them instead of replaying the moves from
  // the input (other calls replay). Null: none kept. Never changes a result.
  std::shared_ptr<const internal::PlanTail> tail;
};

// Fills asset->stats->importance when it is missing (assets converted from other
// formats): the accumulated blending weight over `probes`, measured with the CPU
// reference renderer. Assets trained by `atex train` carry it already.
Status EnsureImportance(Asset* asset, const std::vector<Probe>& probes);

// The importance order of `asset`: Gaussian indices by ascending importance
// (stats.importance, all zero when missing; ties broken by a hash of (seed, index)).
std::vector<uint32_t> ImportanceOrder(const Asset& asset, uint64_t seed);

// The encodings of the streams of an encoded asset (a file's current precision),
// with `base`'s codec settings. Streams the file lacks keep `base`'s encoding.
StatusOr<WriteOptions> EncodingsOfFile(const uint8_t* data, size_t size, const WriteOptions& base);

// Smallest valid asset that `levers` can reach from `asset`: one Gaussian (the most
// important) with prune; SH degree 0 with sh; 1×1 textures with textures or
// all-textures; every stream q8 with encoding (else `write`'s encodings); grids at the
// minimum resolution with grid.
StatusOr<uint64_t> MinimumBytes(const Asset& asset, const WriteOptions& write, int min_grid_resolution = 4,
                                LeverSet levers = kDefaultLevers);
// kBudgetTooSmall, naming MinimumBytes and the levers, when `budget_bytes` is below it; OK otherwise.
Status CheckBudget(const Asset& asset, const WriteOptions& write, uint64_t budget_bytes, int min_grid_resolution = 4,
                   LeverSet levers = kDefaultLevers);

// Builds the plan (see the file comment). `renderer` measures distortion.
StatusOr<Plan> BuildPlan(const Asset& asset, ProbeRenderer* renderer, const PlanOptions& options);

// The result of applying a plan to a budget.
struct Fitted {
  Asset asset;                 // the trimmed asset as decoded from `bytes` (what a reader gets)
  std::vector<uint8_t> bytes;  // the encoded file, size <= budget
  WriteOptions write;          // encodings used
  std::vector<Move> moves;     // the plan's moves that were applied (the last one possibly partial)
  std::vector<uint32_t> kept;  // input indices of the Gaussians kept, ascending
  // True when even the whole plan did not fit and the output is the levers' smallest asset
  // (the one MinimumBytes measures); `moves` is then empty and `plan_end_bytes` says where the
  // plan's moves ended (how far the output jumped below them).
  bool smallest_fallback = false;
  uint64_t plan_end_bytes = 0;
  double apply_seconds = 0;    // ApplyPlan's wall time
  double refill_seconds = 0;   // of which giving slack back below an indivisible last move
  // Whole-file encodes of the replay, the count searches and the refill (not the output's own
  // encode), and their seconds; the refill's part of them.
  int trial_encodes = 0;
  double trial_encode_seconds = 0;
  int refill_encodes = 0;
  double refill_encode_seconds = 0;
  // The refill's time building the states it encodes: its prefixes, trial states and replay.
  double refill_state_seconds = 0;
  // The refill's encodes in order, {move, count, bytes}: `move` the plan index of the move whose
  // count a trial tries and `count` that count; -1 for the encodes that try no count (undoing
  // an indivisible move, the replay's sizes); bytes -1 where the encode failed. Before the
  // trials of a move, its whole count with the output's size then (known, not encoded).
  // For studying the count searches; refill_encodes counts the encodes.
  std::vector<std::array<int64_t, 3>> refill_trials;
};

// Applies moves of `plan` in order until the encoded asset fits `budget_bytes`; the
// last move, if divisible, is cut to the smallest count that fits (an interpolation search
// on the encoded sizes), so that as little as needed is removed; if it is indivisible, the
// moves before it are undone, latest first, to spend the slack again: a divisible one's count
// is searched the same way (the refill stops where one is only partly undone
// or needed whole: the budget binds), an indivisible one is undone whole when the output
// without it still fits. The searches and the refill stop once fewer than budget_bytes / 1024
// bytes are left unused: near the boundary the sizes are mostly compression noise, and each
// trial encodes the whole file. When even the whole plan does not fit (its greedy search can stop a
// few bytes above MinimumBytes: removing one more Gaussian may not shrink the compressed
// file), the output is the smallest asset of the plan's levers, exactly as MinimumBytes
// builds it, so every budget that CheckBudget accepts is met. Fails with kOutOfRange only
// when that one is over the budget too (the message names both sizes).
StatusOr<Fitted> ApplyPlan(const Asset& asset, const Plan& plan, const WriteOptions& write, uint64_t budget_bytes);

// Keeps the ceil(fraction · N) most important Gaussians of `order` (ascending
// importance, e.g. ImportanceOrder of a shared stage-1 asset): the paper's
// fixed-count protocol. `order` must be a permutation of 0..N-1.
StatusOr<Asset> KeepMostImportant(const Asset& asset, const std::vector<uint32_t>& order, double fraction,
                                  std::vector<uint32_t>* kept = nullptr);

// Applies one move to an undecoded asset and its encodings (exposed for tests). `memo` (may
// be null) speeds up texture moves on states that share textures; the result is the same.
Status ApplyMove(const Move& move, const std::vector<uint32_t>& prune_order, Asset* asset, WriteOptions* write,
                 std::vector<uint32_t>* kept, int min_grid_resolution = 4, TextureShrinkMemo* memo = nullptr);

// "80MiB", "80 MB", "1.5GiB", "500KiB", "123456" (bytes; also "B", "KB", "GB" and the
// single letters K, M, G meaning binary units). kInvalidArgument names the text.
StatusOr<uint64_t> ParseByteSize(const std::string& text);

// Report helpers.
nlohmann::json MoveToJson(const Move& move);
nlohmann::json ComponentsToJson(const std::vector<uint8_t>& encoded);

}  // namespace atex::fit
