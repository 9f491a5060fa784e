// The boundary between the training loop (host decisions) and an engine that
// owns parameters and computes (CPU reference or CUDA).
//
// A backend holds the model parameters and their Adam moments. Each Step renders
// a batch of views (deform → project → rasterise), computes the loss, runs the
// backward pass, applies one Adam update and accumulates per-Gaussian statistics.
// The loop reads the statistics, decides on the host (densification, texture
// growth) and sends the edits back, so every backend makes identical decisions.
// With several ranks (data parallelism, docs/multi_gpu.md), each rank runs Step on
// its own views; the backend sums the gradients across the ranks before Adam
// (SetCommunicator), and the trainer sums the statistics it reads before deciding.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "atex/camera.h"
#include "atex/image.h"
#include "atex/model.h"
#include "atex/render.h"  // kDefaultNearPlane
#include "atex/status.h"
#include "atex/train/colour_correction.h"
#include "atex/train/communicator.h"

namespace atex::train {

// Parameter groups, each with its own learning rate.
enum ParamGroup : int {
  kGroupPositions = 0,
  kGroupRotations,
  kGroupLogScales,
  kGroupOpacity,
  kGroupShDc,    // SH coefficient 0
  kGroupShRest,  // SH coefficients 1..K-1
  kGroupTexels,
  kGroupGrid,    // HexPlane planes
  kGroupMlp,     // trunk and heads
  kParamGroupCount
};
const char* ParamGroupName(int group);

// Parameters + Adam state: what a backend loads and saves (checkpoints, edits).
struct ModelState {
  Gaussians gaussians;                      // canonical parameters
  std::optional<TexturePool> textures;
  std::optional<DeformationField> deformation;
  // Adam first and second moments, same shapes as the parameters above.
  Gaussians m_gaussians, v_gaussians;
  std::vector<float> m_texels, v_texels;    // [texel_count][4]
  std::optional<DeformationField> m_deformation, v_deformation;
  std::array<int64_t, kParamGroupCount> adam_steps{};  // per-group update counts (bias correction)
};
// Zero moments shaped like the parameters (for a fresh start or new groups).
void ResetMoments(ModelState* state);
// Zero moments for each group (Gaussians, texels, deformation) whose moments are not shaped
// like its parameters, keeping the others: what Backend::Load does with empty moments.
void FillMissingMoments(ModelState* state);

struct AdamSettings {
  double beta1 = 0.9;
  double beta2 = 0.999;
  double epsilon = 1e-15;  // 4DGaussians / 3DGS
};

// One training view: its camera (with time) and target image [H][W][3].
struct TrainView {
  const Camera* camera = nullptr;
  const Image* target = nullptr;  // null only where the backend's HasTarget(image_key) said true
  uint64_t image_key = 0;  // stable id of the target image (lets a backend cache it on the device)
  // The view's camera colour correction (colour_correction.h): the loss compares the target
  // with gain · rendered + offset. Identity: the render itself.
  ColourAffine colour;
  // False: the backend uses the image for this step only and does not keep a copy (in data
  // parallel training another rank's device keeps it; schedule.h, HomeRank).
  bool keep_on_device = true;
};

struct StepRequest {
  std::array<double, kParamGroupCount> learning_rates{};  // 0 freezes a group
  int active_sh_degree = 0;
  bool apply_deformation = false;  // false in the coarse (static) stage
  bool use_textures = false;
  double lambda_dssim = 0.2;
  // Deformation regularisers (fine stage); zero weights switch them off.
  double plane_tv = 0, time_smoothness = 0, time_l1 = 0;
  bool accumulate_densify_stats = false;
  bool accumulate_texture_stats = false;
  bool accumulate_importance = false;  // sum of blending weights per Gaussian (fitter, pruning)
  int time_bins = 8;
  double time_min = 0, time_max = 1;  // for the temporal bins
  std::array<float, 3> background{0, 0, 0};
  float near_plane = kDefaultNearPlane;
};

struct StepResult {
  double loss = 0;                 // mean over the batch (photometric + regularisers)
  double photometric_loss = 0;
  std::vector<double> view_psnr;   // per view of the batch
  size_t visible = 0;              // (view, Gaussian) pairs with positive radius
  bool finite = true;              // false if a NaN/Inf appeared in the loss or gradients (no update applied)
};

// Per-Gaussian statistics accumulated since the last reset (summed over views and ranks).
struct DensifyStats {
  std::vector<float> grad_norm_sum;  // [N] sum of |dL_k/dm| (NDC units) over visible occurrences
  std::vector<float> visible_count;  // [N]
  std::vector<float> max_radius;     // [N] largest screen radius (pixels)
};
struct TextureStats {
  int bins = 0;
  std::vector<float> demand_sum;    // [N][bins] sum of q over visible occurrences
  std::vector<float> visible_count; // [N][bins]
  std::vector<float> scale_u_sum;   // [N][bins] sum of the deformed scale along axis_u
  std::vector<float> scale_v_sum;   // [N][bins]
};
struct TrainingStats {
  DensifyStats densify;
  TextureStats texture;
  std::vector<float> importance;    // [N] sum of blending weights over all rendered pixels
};
enum StatsKind : int { kStatsDensify = 1, kStatsTexture = 2, kStatsImportance = 4, kStatsAll = 7 };

// Densification / pruning as a gather: new Gaussian j takes old Gaussian source[j]'s
// parameters, texture and Adam moments, then the overrides.
struct GaussianEdit {
  std::vector<uint32_t> source;      // [M]
  std::vector<float> positions;      // [M][3] absolute values, or empty (keep)
  std::vector<float> log_scales;     // [M][3] absolute values, or empty (keep)
  std::vector<uint8_t> reset_moments;  // [M] 1: zero the per-Gaussian Adam moments, or empty (keep all)
  // Opacity reset (3DGS): cap every opacity logit at this value and zero its moments (NaN = off).
  float cap_opacity_logit = std::numeric_limits<float>::quiet_NaN();
};

// Texture growth: new per-Gaussian sides (each >= the old one, in {1, 2, 4}).
struct TextureResize {
  std::vector<uint8_t> heights;  // [N]
  std::vector<uint8_t> widths;   // [N]
  // Stage2Config::rescale_grown_moments: after interpolation, Adam's m × a and v × a² per
  // Gaussian, a = old texel count / new texel count.
  bool rescale_moments = false;
};

struct RenderRequest {
  int active_sh_degree = 3;
  bool apply_deformation = true;
  bool use_textures = true;
  std::array<float, 3> background{0, 0, 0};
  float near_plane = kDefaultNearPlane;
};

// The contract every backend keeps (CPU reference, CUDA; the trainer, the fitter and the
// tools rely on it, and the parity tests check it):
//
// Errors. Every call returns a Status; on an error the backend's state is unspecified
// except where noted, and the caller's remedy is Load (the trainer fails the run):
//   kInvalidArgument  a request that does not fit the loaded model (sizes, indices, a
//                     step asking for deformation or textures the model lacks, a batch
//                     outside 1..MaxBatchViews(), a target image of the wrong size). The
//                     state is unchanged: these are checked before any work.
//   kOutOfRange       values outside what the engine represents (texture sides other
//                     than 1, 2 or 4).
//   kLimitExceeded    out of memory, or a size beyond an engine limit (the CUDA backend's
//                     32-bit texel offsets). The caller may retry smaller.
//   kNoDevice         the device went away (CUDA).
//   kInternal         a bug: an invariant of the backend itself failed.
// Preconditions. Load comes first; every other call refers to the loaded model (its
// Gaussian count N, SH degree, textures and deformation). Cameras must be valid
// (camera.h); views of one Step may have different sizes and times.
// Non-finite steps. When the loss or a gradient of a Step is NaN or ±Inf, the Step
// returns OK with StepResult::finite == false and applies NO update: parameters, Adam
// moments and step counters stay as before the call (statistics of that step may have
// been accumulated). The trainer then restores its last good state (rollback).
// Threads. A backend is used from one thread at a time.
// Content keys of a state's value arrays, from the caller (e.g. 128-bit fingerprints of their
// bytes); a zero key means unknown. Equal non-zero keys must mean equal arrays (the same
// length and bytes): a backend trusts them. `texels` covers the texture layout and the texels;
// `deformation` the whole field (config, grids and MLP).
struct StateKeys {
  using Key = std::array<uint64_t, 2>;
  Key positions{}, rotations{}, log_scales{}, opacity{}, sh{}, time_windows{}, texels{}, deformation{};
};

class Backend {
 public:
  virtual ~Backend() = default;
  virtual std::string name() const = 0;

  // Most views one Step accepts (the CUDA backend keeps per-view scalars in a fixed
  // device buffer of 64). Callers split larger batches; Step refuses them with
  // kInvalidArgument.
  virtual int MaxBatchViews() const { return std::numeric_limits<int>::max(); }

  // Replaces the whole state (parameters, moments, step counters). Resets statistics.
  // The state must be consistent (ValidateAsset's shapes; moments empty or shaped like
  // the parameters: empty moments start at zero).
  virtual Status Load(const ModelState& state) = 0;
  // Load(state) (the same result), where `keys` name the content of the state's value arrays:
  // a backend may keep an array it holds from an earlier LoadKeyed, unchanged since (no Load,
  // Step or edit in between), whose key equals the new one, instead of copying it again. The
  // fitter's probe renders load dozens of states that differ in an array or two. The default
  // loads everything.
  virtual Status LoadKeyed(const ModelState& state, const StateKeys& keys) {
    (void)keys;
    return Load(state);
  }
  // Copies the whole state out (checkpoints, final asset).
  virtual Status Save(ModelState* state) = 0;
  // Copies only the canonical Gaussians out (cheap; densification planning).
  virtual Status ReadGaussians(Gaussians* gaussians) = 0;

  // One optimisation step on 1..MaxBatchViews() views (see the class comment for
  // non-finite steps). Each view's target must be [H][W][3] of its camera's size, or
  // null where HasTarget(image_key) said true. The batch loss is the mean of the views'
  // losses; each group with a non-zero learning rate gets one Adam update.
  virtual StatusOr<StepResult> Step(const StepRequest& request, std::span<const TrainView> views) = 0;

  // Gradients of the last Step, shaped like the parameters: out->gaussians,
  // out->textures->texels and out->deformation hold dL/d(parameter); the moments are
  // left empty. For tests (backend parity) and gradient analysis.
  virtual Status ReadGradients(ModelState* out) = 0;

  // Statistics accumulated since the last reset, for the kinds in `kinds` (StatsKind
  // bits); the other members of `stats` are left as they are.
  virtual Status ReadStats(int kinds, TrainingStats* stats) = 0;
  virtual Status ResetStats(int kinds) = 0;

  // Gathers the Gaussians (edit.source indices < N, overrides sized to the new count;
  // kInvalidArgument otherwise, state unchanged). Resets statistics.
  virtual Status ApplyEdit(const GaussianEdit& edit) = 0;
  // Attaches textures (zero texels, zero moments) with the given layout, or replaces the
  // layout. layout.size() must be N.
  virtual Status AttachTextures(const TexturePool& layout) = 0;
  // Resamples the texels to new sides (N entries each, sides in {1, 2, 4}: kOutOfRange
  // otherwise). kInvalidArgument when the model has no textures.
  virtual Status ResizeTextures(const TextureResize& resize) = 0;

  // Renders [H][W][3] at the camera's time (unclamped; the request's background).
  virtual StatusOr<Image> Render(const Camera& camera, const RenderRequest& request) = 0;

  // Data parallelism. With a communicator of world size R attached, every later Step is
  // collective: the loss is normalised by the GLOBAL batch (views.size() × R; every rank
  // passes the same number of views), the photometric gradients of all groups, the loss and
  // the finiteness are summed across the ranks, and the deformation regularisers (which
  // depend on the parameters alone) are added once after that sum, before the (then
  // identical) Adam update, so that R ranks with B/R views each make the update of one rank
  // with all B views. StepResult::view_psnr stays this rank's.
  // Statistics stay per rank (the trainer sums what ReadStats returns). null detaches (one
  // rank). The communicator must outlive its use. Backends without the support accept only
  // null or a single rank: kUnsupported otherwise.
  virtual Status SetCommunicator(Communicator* comm) {
    if (comm == nullptr || comm->world_size() == 1) return Status::Ok();
    return MakeError(StatusCode::kUnsupported, "backend ", name(), " does not train with ", comm->world_size(),
                     " ranks (", comm->name(), " communicator)");
  }

  // Peak device memory in bytes since creation (0 if not tracked).
  virtual uint64_t PeakMemoryBytes() const { return 0; }
  // True when the backend holds the target image of `image_key` already (a Step may then
  // get that view with target == nullptr, sparing the caller a decode).
  virtual bool HasTarget(uint64_t /*image_key*/) const { return false; }
  // Time spent per stage when the backend was created with profiling on
  // ({"deform_forward_ms": ..., ...}); an empty object otherwise.
  virtual nlohmann::json Profile() const { return nlohmann::json::object(); }
};

// The CPU reference backend (libatex/src/train/cpu_backend.cc).
std::unique_ptr<Backend> MakeCpuBackend(const AdamSettings& adam = {});

}  // namespace atex::train
