// For tests: a Backend that forwards every call to another one (the CPU backend by
// default), so that a test overrides only the calls it perturbs or counts.
#pragma once

#include <limits>
#include <memory>
#include <span>
#include <string>
#include <utility>

#include "atex/train/backend.h"

namespace atex::train {

class ForwardingBackend : public Backend {
 public:
  explicit ForwardingBackend(std::unique_ptr<Backend> inner = MakeCpuBackend()) : inner_(std::move(inner)) {}
  std::string name() const override { return "forwarding(" + inner_->name() + ")"; }
  int MaxBatchViews() const override { return inner_->MaxBatchViews(); }
  Status Load(const ModelState& s) override { return inner_->Load(s); }
  Status LoadKeyed(const ModelState& s, const StateKeys& k) override { return inner_->LoadKeyed(s, k); }
  Status Save(ModelState* s) override { return inner_->Save(s); }
  Status ReadGaussians(Gaussians* g) override { return inner_->ReadGaussians(g); }
  StatusOr<StepResult> Step(const StepRequest& r, std::span<const TrainView> v) override { return inner_->Step(r, v); }
  Status ReadGradients(ModelState* g) override { return inner_->ReadGradients(g); }
  Status ReadStats(int k, TrainingStats* s) override { return inner_->ReadStats(k, s); }
  Status ResetStats(int k) override { return inner_->ResetStats(k); }
  Status ApplyEdit(const GaussianEdit& e) override { return inner_->ApplyEdit(e); }
  Status AttachTextures(const TexturePool& l) override { return inner_->AttachTextures(l); }
  Status ResizeTextures(const TextureResize& r) override { return inner_->ResizeTextures(r); }
  StatusOr<Image> Render(const Camera& c, const RenderRequest& r) override { return inner_->Render(c, r); }
  Status SetCommunicator(Communicator* c) override { return inner_->SetCommunicator(c); }

 protected:
  Backend& inner() { return *inner_; }

 private:
  std::unique_ptr<Backend> inner_;
};

// The inner backend, except that step number `bad_step` (0-based, counting every Step call)
// reports a non-finite loss and applies nothing, as a backend must (backend.h). Counts the
// Loads (a rollback is one) and keeps the last request that reached the inner backend.
class NonFiniteAtStep final : public ForwardingBackend {
 public:
  explicit NonFiniteAtStep(int bad_step) : bad_step_(bad_step) {}
  Status Load(const ModelState& s) override {
    ++loads_;
    return ForwardingBackend::Load(s);
  }
  StatusOr<StepResult> Step(const StepRequest& r, std::span<const TrainView> v) override {
    if (steps_++ == bad_step_) {
      StepResult bad;
      bad.loss = std::numeric_limits<double>::quiet_NaN();
      bad.finite = false;
      return bad;
    }
    last_request_ = r;
    return ForwardingBackend::Step(r, v);
  }
  int loads() const { return loads_; }
  const StepRequest& last_request() const { return last_request_; }

 private:
  int bad_step_;
  int steps_ = 0;
  int loads_ = 0;
  StepRequest last_request_;
};

}  // namespace atex::train
