// The CPU reference backend: the same Step as the CUDA backend, composed from the
// reference modules (deform, render, metrics) in float. Slow but complete; it makes
// every training feature testable without a GPU.
#include <algorithm>
#include <cmath>
#include <limits>

#include "atex/deform.h"
#include "atex/detail/adam.h"
#include "atex/detail/texture.h"
#include "atex/metrics.h"
#include "atex/render.h"
#include "atex/train/backend.h"
#include "atex/train/communicator.h"
#include "data_parallel.h"
#include "tensor_sums.h"

namespace atex::train {

namespace {

// Gathers rows of `width` values: out[j] = in[source[j]].
std::vector<float> GatherRows(const std::vector<float>& in, int width, const std::vector<uint32_t>& source,
                              const std::vector<uint8_t>* zero_rows) {
  std::vector<float> out(source.size() * width);
  for (size_t j = 0; j < source.size(); ++j) {
    if (zero_rows && !zero_rows->empty() && (*zero_rows)[j]) continue;
    std::copy_n(in.begin() + size_t(source[j]) * width, width, out.begin() + j * width);
  }
  return out;
}

Gaussians GatherGaussians(const Gaussians& g, const std::vector<uint32_t>& source,
                          const std::vector<uint8_t>* zero_rows) {
  Gaussians out;
  out.sh_degree = g.sh_degree;
  out.positions = GatherRows(g.positions, 3, source, zero_rows);
  out.rotations = GatherRows(g.rotations, 4, source, zero_rows);
  out.log_scales = GatherRows(g.log_scales, 3, source, zero_rows);
  out.opacity_logits = GatherRows(g.opacity_logits, 1, source, zero_rows);
  out.sh = GatherRows(g.sh, 3 * g.sh_coeffs(), source, zero_rows);
  if (g.has_time_windows()) out.time_windows = GatherRows(g.time_windows, 2, source, zero_rows);
  return out;
}

class CpuBackend final : public Backend {
 public:
  explicit CpuBackend(const AdamSettings& adam) : adam_(adam) {}
  std::string name() const override { return "cpu"; }

  Status Load(const ModelState& state) override {
    state_ = state;
    FillMissingMoments(&state_);  // per group: empty moments start at zero
    if (state_.textures) state_.textures->RebuildOffsets();
    return ResetStats(kStatsAll);
  }

  Status Save(ModelState* state) override {
    *state = state_;
    return Status::Ok();
  }

  Status ReadGaussians(Gaussians* g) override {
    *g = state_.gaussians;
    return Status::Ok();
  }

  // One view of a step: its forward render, loss and backward pass; its gradients are appended
  // to the per-view lists (`view_fields` only with deformation, `view_texels` only `textured`),
  // its loss share to `photometric`, its PSNR and visible count to `result`. Returns false, with
  // nothing appended, when the loss or dL/dimage is not finite (e.g. a corrupt target frame).
  StatusOr<bool> StepView(const StepRequest& request, const TrainView& view, bool textured, float batch,
                          const RenderSettings& settings, double* photometric, StepResult* result,
                          std::vector<Gaussians>* view_grads, std::vector<std::vector<float>>* view_texels,
                          std::vector<DeformationField>* view_fields) {
    const size_t n = state_.gaussians.size();
    const Camera& camera = *view.camera;
    const Image& target = *view.target;
    if (target.width != camera.width || target.height != camera.height || target.channels != 3) {
      return MakeError(StatusCode::kInvalidArgument, "target image ", target.width, "x", target.height, "x",
                       target.channels, " does not match camera ", camera.width, "x", camera.height);
    }
    Gaussians deformed;
    DeformCache cache;
    const Gaussians* rendered_gaussians = &state_.gaussians;
    if (request.apply_deformation) {
      ATEX_RETURN_IF_ERROR(DeformForward(*state_.deformation, state_.gaussians, camera.time, &deformed, &cache));
      rendered_gaussians = &deformed;
    }
    const TexturePool* textures = textured ? &*state_.textures : nullptr;
    ATEX_ASSIGN_OR_RETURN(RenderOutput out, RenderForward<float>(camera, *rendered_gaussians, textures, settings));
    std::vector<float> grad_image(out.color.size());
    // The camera's colour correction acts on a copy: the backward pass needs the render itself.
    const size_t pixels = size_t(camera.width) * camera.height;
    std::vector<float> corrected = view.colour.IsIdentity() ? std::vector<float>{} : out.color;
    if (!corrected.empty()) view.colour.Apply(corrected.data(), pixels);
    const std::vector<float>* compared = corrected.empty() ? &out.color : &corrected;
    const double loss = PhotometricLoss<float>(compared->data(), target.pixels.data(), camera.width,
                                               camera.height, request.lambda_dssim, grad_image.data());
    if (!view.colour.IsIdentity()) view.colour.ScaleGradient(grad_image.data(), pixels);
    *photometric += loss / batch;
    for (float& g : grad_image) g /= batch;
    // A NaN/Inf in the loss or dL/dimage (e.g. a corrupt target frame) is reported as a
    // non-finite step, like one in the parameter gradients, so that the loop rolls back;
    // RenderBackward would otherwise refuse the gradient with an error and end training.
    // (With several ranks, the others still meet this rank in Step's reduction.)
    if (!std::isfinite(loss) || !AllFinite(grad_image)) return false;
    double sse = 0;
    for (size_t k = 0; k < compared->size(); ++k) {
      const double d = double((*compared)[k]) - target.pixels[k];
      sse += d * d;
    }
    const double mse = sse / compared->size();
    result->view_psnr.push_back(mse > 0 ? -10.0 * std::log10(mse) : 99.0);

    RenderGradients rgrads;
    ATEX_RETURN_IF_ERROR(RenderBackward<float>(camera, *rendered_gaussians, textures, settings, out,
                                               grad_image.data(), nullptr, &rgrads));
    if (request.apply_deformation) {
      Gaussians view_grad;
      view_grad.sh_degree = state_.gaussians.sh_degree;
      view_grad.Resize(n);
      DeformationField view_field = ZerosLike(*state_.deformation);
      ATEX_RETURN_IF_ERROR(DeformBackward(*state_.deformation, state_.gaussians, camera.time, cache,
                                          rgrads.gaussians, &view_field, &view_grad));
      view_grads->push_back(std::move(view_grad));
      view_fields->push_back(std::move(view_field));
    } else {
      view_grads->push_back(std::move(rgrads.gaussians));
    }
    if (textured) {
      rgrads.texels.resize(state_.textures->texels.size(), 0.0f);
      view_texels->push_back(std::move(rgrads.texels));
    }
    AccumulateStats(request, camera, *rendered_gaussians, out, rgrads, batch, textured);
    for (size_t i = 0; i < n; ++i) result->visible += out.radius[i] > 0 ? 1 : 0;
    return true;
  }

  StatusOr<StepResult> Step(const StepRequest& request, std::span<const TrainView> views) override {
    if (views.empty()) return MakeError(StatusCode::kInvalidArgument, "CPU backend: empty batch");
    if (request.apply_deformation && !state_.deformation) {
      return MakeError(StatusCode::kInvalidArgument, "step asks for deformation but the model has none");
    }
    const bool textured = request.use_textures && state_.textures.has_value();
    const size_t n = state_.gaussians.size();
    Communicator& comm = comm_ != nullptr ? *comm_ : single_rank_;
    const int world = comm.world_size();
    // The global batch: with R ranks of views.size() views each, every view's loss is divided by
    // the batch of all ranks, so that the summed gradients are those of one rank with all views.
    const float batch = static_cast<float>(views.size()) * static_cast<float>(world);

    // Each view's gradients apart, summed as a tree after the loop (TreeSum).
    std::vector<Gaussians> view_grads;
    std::vector<std::vector<float>> view_texels;
    std::vector<DeformationField> view_fields;

    RenderSettings settings;
    settings.background = request.background;
    settings.near_plane = request.near_plane;
    settings.active_sh_degree = request.active_sh_degree;

    StepResult result;
    double photometric = 0;
    bool nonfinite_image = false;
    for (const TrainView& view : views) {
      ATEX_ASSIGN_OR_RETURN(const bool finite, StepView(request, view, textured, batch, settings, &photometric, &result,
                                                        &view_grads, &view_texels, &view_fields));
      if (!finite) {
        nonfinite_image = true;
        break;
      }
    }
    Gaussians grad;
    grad.sh_degree = state_.gaussians.sh_degree;
    grad.Resize(n);
    std::vector<float> grad_texels(textured ? state_.textures->texels.size() : 0, 0.0f);
    std::optional<DeformationField> grad_field;
    if (request.apply_deformation) grad_field = ZerosLike(*state_.deformation);
    if (!nonfinite_image) {
      grad = TreeSum(view_grads, 0, view_grads.size());
      if (textured) grad_texels = TreeSum(view_texels, 0, view_texels.size());
      if (request.apply_deformation) grad_field = TreeSum(view_fields, 0, view_fields.size());
    }
    const bool finite_here = !nonfinite_image && std::isfinite(photometric) && AllFinite(grad) &&
                             AllFinite(grad_texels) && (!grad_field || AllFinite(*grad_field));
    // One collective for the scalars decides for every rank whether the step is applied.
    double scalars[3] = {photometric, finite_here ? 0.0 : 1.0, static_cast<double>(result.visible)};
    ATEX_RETURN_IF_ERROR(comm.AllReduceSum(scalars, 3));
    result.visible = static_cast<size_t>(scalars[2]);
    if (scalars[1] != 0) {
      result.photometric_loss = result.loss = std::numeric_limits<double>::quiet_NaN();
      result.finite = false;
      return result;
    }
    result.photometric_loss = scalars[0];
    result.loss = scalars[0];
    ATEX_RETURN_IF_ERROR(AllReduceSum(comm, &grad));
    ATEX_RETURN_IF_ERROR(comm.AllReduceSum(grad_texels.data(), grad_texels.size()));
    if (grad_field) ATEX_RETURN_IF_ERROR(AllReduceSum(comm, &*grad_field));
    // The regularisers depend on the parameters alone (the same on every rank): added once,
    // after the sum over the ranks.
    if (request.apply_deformation &&
        (request.plane_tv > 0 || request.time_smoothness > 0 || request.time_l1 > 0)) {
      RegularizerWeights weights{static_cast<float>(request.plane_tv), static_cast<float>(request.time_smoothness),
                                 static_cast<float>(request.time_l1)};
      result.loss += DeformRegularizer(*state_.deformation, weights, &*grad_field);
    }
    // (A sum of finite values can overflow.)
    result.finite = std::isfinite(result.loss) && AllFinite(grad) && AllFinite(grad_texels) &&
                    (!grad_field || AllFinite(*grad_field));
    if (!result.finite) return result;

    ApplyAdam(request, grad, textured ? &grad_texels : nullptr, grad_field ? &*grad_field : nullptr);
    last_grad_ = std::move(grad);
    last_grad_texels_ = std::move(grad_texels);
    last_grad_field_ = std::move(grad_field);
    return result;
  }

  Status SetCommunicator(Communicator* comm) override {
    comm_ = comm;
    return Status::Ok();
  }

  Status ReadGradients(ModelState* out) override {
    *out = ModelState{};
    out->gaussians = last_grad_;
    if (state_.textures) {
      out->textures = *state_.textures;
      out->textures->texels = last_grad_texels_;
      out->textures->texels.resize(state_.textures->texels.size(), 0.0f);
    }
    out->deformation = last_grad_field_;
    return Status::Ok();
  }

  Status ReadStats(int kinds, TrainingStats* stats) override {
    if (kinds & kStatsDensify) stats->densify = stats_.densify;
    if (kinds & kStatsTexture) stats->texture = stats_.texture;
    if (kinds & kStatsImportance) stats->importance = stats_.importance;
    return Status::Ok();
  }

  Status ResetStats(int kinds) override {
    const size_t n = state_.gaussians.size();
    if (kinds & kStatsDensify) {
      stats_.densify.grad_norm_sum.assign(n, 0.0f);
      stats_.densify.visible_count.assign(n, 0.0f);
      stats_.densify.max_radius.assign(n, 0.0f);
    }
    if (kinds & kStatsTexture) {
      auto& t = stats_.texture;
      t.bins = bins_;
      for (auto* v : {&t.demand_sum, &t.visible_count, &t.scale_u_sum, &t.scale_v_sum}) v->assign(n * bins_, 0.0f);
    }
    if (kinds & kStatsImportance) stats_.importance.assign(n, 0.0f);
    return Status::Ok();
  }

  Status ApplyEdit(const GaussianEdit& edit) override {
    const size_t n = state_.gaussians.size(), m = edit.source.size();
    for (uint32_t s : edit.source) {
      if (s >= n) return MakeError(StatusCode::kInvalidArgument, "edit source ", s, " of ", n, " Gaussians");
    }
    if ((!edit.positions.empty() && edit.positions.size() != m * 3) ||
        (!edit.log_scales.empty() && edit.log_scales.size() != m * 3) ||
        (!edit.reset_moments.empty() && edit.reset_moments.size() != m)) {
      return MakeError(StatusCode::kInvalidArgument, "edit override arrays do not match ", m, " Gaussians");
    }
    Gaussians g = GatherGaussians(state_.gaussians, edit.source, nullptr);
    if (!edit.positions.empty()) g.positions = edit.positions;
    if (!edit.log_scales.empty()) g.log_scales = edit.log_scales;
    state_.m_gaussians = GatherGaussians(state_.m_gaussians, edit.source, &edit.reset_moments);
    state_.v_gaussians = GatherGaussians(state_.v_gaussians, edit.source, &edit.reset_moments);
    state_.gaussians = std::move(g);
    if (state_.textures) {
      const TexturePool& old = *state_.textures;
      TexturePool pool;
      std::vector<float> m_texels, v_texels;
      for (uint32_t s : edit.source) {
        pool.heights.push_back(old.heights[s]);
        pool.widths.push_back(old.widths[s]);
        pool.axis_u.push_back(old.axis_u[s]);
        pool.axis_v.push_back(old.axis_v[s]);
        const size_t from = old.offsets[s] * 4, to = old.offsets[s + 1] * 4;
        pool.texels.insert(pool.texels.end(), old.texels.begin() + from, old.texels.begin() + to);
        m_texels.insert(m_texels.end(), state_.m_texels.begin() + from, state_.m_texels.begin() + to);
        v_texels.insert(v_texels.end(), state_.v_texels.begin() + from, state_.v_texels.begin() + to);
      }
      pool.RebuildOffsets();
      state_.textures = std::move(pool);
      state_.m_texels = std::move(m_texels);
      state_.v_texels = std::move(v_texels);
    }
    if (!std::isnan(edit.cap_opacity_logit)) {
      for (float& o : state_.gaussians.opacity_logits) o = std::min(o, edit.cap_opacity_logit);
      std::fill(state_.m_gaussians.opacity_logits.begin(), state_.m_gaussians.opacity_logits.end(), 0.0f);
      std::fill(state_.v_gaussians.opacity_logits.begin(), state_.v_gaussians.opacity_logits.end(), 0.0f);
    }
    return ResetStats(kStatsAll);
  }

  Status AttachTextures(const TexturePool& layout) override {
    if (layout.size() != state_.gaussians.size()) {
      return MakeError(StatusCode::kInvalidArgument, "texture layout for ", layout.size(), " Gaussians, model has ",
                       state_.gaussians.size());
    }
    TexturePool pool = layout;
    pool.RebuildOffsets();
    if (pool.texels.size() != pool.texel_count() * 4) pool.texels.assign(pool.texel_count() * 4, 0.0f);
    state_.m_texels.assign(pool.texels.size(), 0.0f);
    state_.v_texels.assign(pool.texels.size(), 0.0f);
    state_.textures = std::move(pool);
    state_.adam_steps[kGroupTexels] = 0;
    return ResetStats(kStatsTexture);
  }

  Status ResizeTextures(const TextureResize& resize) override {
    if (!state_.textures) return MakeError(StatusCode::kInvalidArgument, "resize of textures the model does not have");
    std::vector<float>* extra[] = {&state_.m_texels, &state_.v_texels};
    ATEX_ASSIGN_OR_RETURN(TexturePool grown,
                          atex::ResizeTextures<float>(*state_.textures, resize.heights, resize.widths, extra));
    if (resize.rescale_moments) {
      const TexturePool& old = *state_.textures;
      for (size_t i = 0; i < grown.size(); ++i) {
        const float share =
            detail::GrownMomentShare<float>(old.heights[i], old.widths[i], grown.heights[i], grown.widths[i]);
        for (size_t k = size_t(grown.offsets[i]) * 4; k < size_t(grown.offsets[i + 1]) * 4; ++k) {
          state_.m_texels[k] *= share;
          state_.v_texels[k] *= share * share;
        }
      }
    }
    state_.textures = std::move(grown);
    return Status::Ok();
  }

  StatusOr<Image> Render(const Camera& camera, const RenderRequest& request) override {
    Gaussians deformed;
    const Gaussians* g = &state_.gaussians;
    if (request.apply_deformation && state_.deformation) {
      ATEX_RETURN_IF_ERROR(DeformForward(*state_.deformation, state_.gaussians, camera.time, &deformed, nullptr));
      g = &deformed;
    }
    RenderSettings settings;
    settings.background = request.background;
    settings.near_plane = request.near_plane;
    settings.active_sh_degree = request.active_sh_degree;
    const TexturePool* textures = request.use_textures && state_.textures ? &*state_.textures : nullptr;
    ATEX_ASSIGN_OR_RETURN(RenderOutput out, RenderForward<float>(camera, *g, textures, settings));
    return RenderedImage(out);
  }

 private:
  void AccumulateStats(const StepRequest& request, const Camera& camera, const Gaussians& rendered,
                       const RenderOutput& out, const RenderGradients& rgrads, float batch, bool textured) {
    const size_t n = rendered.size();
    if (request.accumulate_importance) AddInto(&stats_.importance, out.importance);
    const bool densify = request.accumulate_densify_stats;
    const bool texture = request.accumulate_texture_stats && textured;
    if (!densify && !texture) return;
    if (texture && bins_ != request.time_bins) {
      bins_ = request.time_bins;
      (void)ResetStats(kStatsTexture);
    }
    const double span = request.time_max - request.time_min;
    const double unit = span > 0 ? (camera.time - request.time_min) / span : 0.0;
    const int bin = std::clamp(static_cast<int>(std::floor(unit * bins_)), 0, bins_ - 1);
    for (size_t i = 0; i < n; ++i) {
      if (out.radius[i] <= 0) continue;  // visible = positive rasterised radius
      // Demand in NDC units of the single view's loss (conventions §6).
      const float gx = rgrads.mean2d[2 * i] * 0.5f * camera.width;
      const float gy = rgrads.mean2d[2 * i + 1] * 0.5f * camera.height;
      const float demand = std::sqrt(gx * gx + gy * gy) * batch;
      if (densify) {
        stats_.densify.grad_norm_sum[i] += demand;
        stats_.densify.visible_count[i] += 1.0f;
        stats_.densify.max_radius[i] = std::max(stats_.densify.max_radius[i], static_cast<float>(out.radius[i]));
      }
      if (texture) {
        const size_t k = i * bins_ + bin;
        auto& t = stats_.texture;
        t.demand_sum[k] += demand;
        t.visible_count[k] += 1.0f;
        t.scale_u_sum[k] += std::exp(rendered.log_scales[3 * i + state_.textures->axis_u[i]]);
        t.scale_v_sum[k] += std::exp(rendered.log_scales[3 * i + state_.textures->axis_v[i]]);
      }
    }
  }

  // One Adam update of `values` with gradient `grads`; element e uses lr_first when
  // (e % period) < split (the CUDA backend's rule, for SH DC vs rest).
  void Adam(std::vector<float>* values, const std::vector<float>& grads, std::vector<float>* m,
            std::vector<float>* v, int group, double lr_first, double lr_rest, int period, int split) {
    if (lr_first == 0.0 && lr_rest == 0.0) return;
    const int64_t step = ++state_.adam_steps[group];
    const float bias1 = static_cast<float>(1.0 - std::pow(adam_.beta1, static_cast<double>(step)));
    const float bias2 = static_cast<float>(1.0 - std::pow(adam_.beta2, static_cast<double>(step)));
    const float b1 = static_cast<float>(adam_.beta1), b2 = static_cast<float>(adam_.beta2);
    const float eps = static_cast<float>(adam_.epsilon);
    const float lr_a = static_cast<float>(lr_first), lr_b = static_cast<float>(lr_rest);
    for (size_t e = 0; e < values->size(); ++e) {
      const float lr = static_cast<int>(e % period) < split ? lr_a : lr_b;
      if (lr == 0.0f) continue;
      detail::AdamUpdate((*values)[e], (*m)[e], (*v)[e], grads[e], lr, b1, b2, eps, bias1, bias2);
    }
  }

  void AdamField(DeformationField* field, const DeformationField& grad, DeformationField* m, DeformationField* v,
                 int group, double lr, bool planes) {
    if (lr == 0.0) return;
    // All tensors of the group share one update count (as one PyTorch param group would).
    const int64_t before = state_.adam_steps[group];
    auto one = [&](std::vector<float>* values, const std::vector<float>& g, std::vector<float>* mm,
                   std::vector<float>* vv) {
      state_.adam_steps[group] = before;
      Adam(values, g, mm, vv, group, lr, lr, 1, 1);
    };
    if (planes) {
      for (size_t s = 0; s < field->planes.size(); ++s) {
        for (int p = 0; p < kNumHexPlanes; ++p) {
          one(&field->planes[s][p], grad.planes[s][p], &m->planes[s][p], &v->planes[s][p]);
        }
      }
    } else {
      for (size_t l = 0; l < field->trunk.size(); ++l) {
        one(&field->trunk[l].weight, grad.trunk[l].weight, &m->trunk[l].weight, &v->trunk[l].weight);
        one(&field->trunk[l].bias, grad.trunk[l].bias, &m->trunk[l].bias, &v->trunk[l].bias);
      }
      for (int h = 0; h < kNumDeformHeads; ++h) {
        for (int k = 0; k < 2; ++k) {
          one(&field->heads[h][k].weight, grad.heads[h][k].weight, &m->heads[h][k].weight, &v->heads[h][k].weight);
          one(&field->heads[h][k].bias, grad.heads[h][k].bias, &m->heads[h][k].bias, &v->heads[h][k].bias);
        }
      }
    }
    state_.adam_steps[group] = before + 1;
  }

  void ApplyAdam(const StepRequest& request, const Gaussians& grad, const std::vector<float>* grad_texels,
                 const DeformationField* grad_field) {
    const auto& lr = request.learning_rates;
    Gaussians& g = state_.gaussians;
    Gaussians& m = state_.m_gaussians;
    Gaussians& v = state_.v_gaussians;
    Adam(&g.positions, grad.positions, &m.positions, &v.positions, kGroupPositions, lr[kGroupPositions],
         lr[kGroupPositions], 1, 1);
    Adam(&g.rotations, grad.rotations, &m.rotations, &v.rotations, kGroupRotations, lr[kGroupRotations],
         lr[kGroupRotations], 1, 1);
    Adam(&g.log_scales, grad.log_scales, &m.log_scales, &v.log_scales, kGroupLogScales, lr[kGroupLogScales],
         lr[kGroupLogScales], 1, 1);
    Adam(&g.opacity_logits, grad.opacity_logits, &m.opacity_logits, &v.opacity_logits, kGroupOpacity,
         lr[kGroupOpacity], lr[kGroupOpacity], 1, 1);
    if (lr[kGroupShDc] != 0 || lr[kGroupShRest] != 0) {
      ++state_.adam_steps[kGroupShRest];
      Adam(&g.sh, grad.sh, &m.sh, &v.sh, kGroupShDc, lr[kGroupShDc], lr[kGroupShRest], 3 * g.sh_coeffs(), 3);
    }
    if (grad_texels) {
      Adam(&state_.textures->texels, *grad_texels, &state_.m_texels, &state_.v_texels, kGroupTexels,
           lr[kGroupTexels], lr[kGroupTexels], 1, 1);
    }
    if (grad_field) {
      if (!state_.m_deformation) state_.m_deformation = ZerosLike(*state_.deformation);
      if (!state_.v_deformation) state_.v_deformation = ZerosLike(*state_.deformation);
      AdamField(&*state_.deformation, *grad_field, &*state_.m_deformation, &*state_.v_deformation, kGroupGrid,
                lr[kGroupGrid], true);
      AdamField(&*state_.deformation, *grad_field, &*state_.m_deformation, &*state_.v_deformation, kGroupMlp,
                lr[kGroupMlp], false);
    }
  }

  AdamSettings adam_;
  Communicator* comm_ = nullptr;          // SetCommunicator; null: one rank
  SingleRankCommunicator single_rank_;
  ModelState state_;
  TrainingStats stats_;
  Gaussians last_grad_;                           // gradients of the last Step (ReadGradients)
  std::vector<float> last_grad_texels_;
  std::optional<DeformationField> last_grad_field_;
  int bins_ = 8;
};

}  // namespace

std::unique_ptr<Backend> MakeCpuBackend(const AdamSettings& adam) { return std::make_unique<CpuBackend>(adam); }

}  // namespace atex::train
