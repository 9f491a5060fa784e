#include "deform/linear_lt.h"

#include <memory>

#include "cuda_check.h"

namespace atex::cuda::deform_detail {
namespace {

// The workspace cuBLASLt's documentation recommends for Hopper; some algorithms (split-K)
// are only offered when the preference allows a workspace.
constexpr size_t kWorkspaceBytes = size_t{32} << 20;
// Densification changes N every 100 steps; older plans are dropped beyond this many.
constexpr size_t kMaxPlans = 32;

uint32_t Alignment(const void* p) {
  const auto address = reinterpret_cast<uintptr_t>(p);
  uint32_t a = 16;
  while (a > 1 && address % a != 0) a /= 2;
  return a;
}

Status LtStatus(cublasStatus_t s, const char* what) { return CublasStatus(s, what, __FILE__, __LINE__); }

// RAII owners of the descriptors of one call.
struct DescDeleter {
  void operator()(cublasLtMatmulDescOpaque_t* d) const { cublasLtMatmulDescDestroy(d); }
};
struct LayoutDeleter {
  void operator()(cublasLtMatrixLayoutOpaque_t* l) const { cublasLtMatrixLayoutDestroy(l); }
};
struct PreferenceDeleter {
  void operator()(cublasLtMatmulPreferenceOpaque_t* p) const { cublasLtMatmulPreferenceDestroy(p); }
};
using Desc = std::unique_ptr<cublasLtMatmulDescOpaque_t, DescDeleter>;
using Layout = std::unique_ptr<cublasLtMatrixLayoutOpaque_t, LayoutDeleter>;
using Preference = std::unique_ptr<cublasLtMatmulPreferenceOpaque_t, PreferenceDeleter>;

Status MakeLayout(uint64_t rows, uint64_t cols, int64_t ld, Layout* out) {
  cublasLtMatrixLayout_t layout = nullptr;
  ATEX_RETURN_IF_ERROR(LtStatus(cublasLtMatrixLayoutCreate(&layout, CUDA_R_32F, rows, cols, ld), "MatrixLayoutCreate"));
  out->reset(layout);
  return Status::Ok();
}

}  // namespace

FusedLinearRelu::~FusedLinearRelu() {
  if (handle_) cublasLtDestroy(handle_);
}

Status FusedLinearRelu::Forward(const float* w, int in, int out, const float* x, int ldx, int rows, const float* bias,
                                float* y, int ldy, bool allow_tf32, cudaStream_t stream, bool* fused) {
  *fused = false;
  if (rows <= 0) {
    *fused = true;
    return Status::Ok();
  }
  if (!handle_) ATEX_RETURN_IF_ERROR(LtStatus(cublasLtCreate(&handle_), "cublasLtCreate"));
  if (workspace_.size() < kWorkspaceBytes) ATEX_RETURN_IF_ERROR(workspace_.Resize(kWorkspaceBytes));

  // Column-major view, as in linear_gemm.cc: Y (out x rows) = W^T (out x in) * X (in x rows)
  // with W stored as the column-major (in x out) matrix of leading dimension in.
  cublasLtMatmulDesc_t raw_desc = nullptr;
  ATEX_RETURN_IF_ERROR(LtStatus(
      cublasLtMatmulDescCreate(&raw_desc, allow_tf32 ? CUBLAS_COMPUTE_32F_FAST_TF32 : CUBLAS_COMPUTE_32F, CUDA_R_32F),
      "MatmulDescCreate"));
  Desc desc(raw_desc);
  const cublasOperation_t transpose = CUBLAS_OP_T, none = CUBLAS_OP_N;
  const cublasLtEpilogue_t epilogue = CUBLASLT_EPILOGUE_RELU_BIAS;
  const cudaDataType_t bias_type = CUDA_R_32F;
  ATEX_RETURN_IF_ERROR(LtStatus(
      cublasLtMatmulDescSetAttribute(raw_desc, CUBLASLT_MATMUL_DESC_TRANSA, &transpose, sizeof(transpose)), "TRANSA"));
  ATEX_RETURN_IF_ERROR(
      LtStatus(cublasLtMatmulDescSetAttribute(raw_desc, CUBLASLT_MATMUL_DESC_TRANSB, &none, sizeof(none)), "TRANSB"));
  ATEX_RETURN_IF_ERROR(
      LtStatus(cublasLtMatmulDescSetAttribute(raw_desc, CUBLASLT_MATMUL_DESC_EPILOGUE, &epilogue, sizeof(epilogue)),
               "EPILOGUE"));
  ATEX_RETURN_IF_ERROR(
      LtStatus(cublasLtMatmulDescSetAttribute(raw_desc, CUBLASLT_MATMUL_DESC_BIAS_POINTER, &bias, sizeof(bias)),
               "BIAS_POINTER"));
  ATEX_RETURN_IF_ERROR(
      LtStatus(cublasLtMatmulDescSetAttribute(raw_desc, CUBLASLT_MATMUL_DESC_BIAS_DATA_TYPE, &bias_type,
                                              sizeof(bias_type)),
               "BIAS_DATA_TYPE"));
  Layout a, b, c;
  ATEX_RETURN_IF_ERROR(MakeLayout(in, out, in, &a));
  ATEX_RETURN_IF_ERROR(MakeLayout(in, rows, ldx, &b));
  ATEX_RETURN_IF_ERROR(MakeLayout(out, rows, ldy, &c));

  const uint32_t align_w = Alignment(w), align_x = Alignment(x), align_y = Alignment(y), align_bias = Alignment(bias);
  const uint32_t alignments = align_w | align_x << 8 | align_y << 16 | align_bias << 24;
  Plan* plan = nullptr;
  for (Plan& p : plans_) {
    if (p.in == in && p.out == out && p.rows == rows && p.ldx == ldx && p.ldy == ldy && p.tf32 == allow_tf32 &&
        p.alignments == alignments) {
      plan = &p;
      break;
    }
  }
  if (!plan) {
    cublasLtMatmulPreference_t raw_preference = nullptr;
    ATEX_RETURN_IF_ERROR(LtStatus(cublasLtMatmulPreferenceCreate(&raw_preference), "PreferenceCreate"));
    Preference preference(raw_preference);
    const size_t workspace = kWorkspaceBytes;
    const struct {
      cublasLtMatmulPreferenceAttributes_t attribute;
      uint32_t bytes;
    } minimum[] = {{CUBLASLT_MATMUL_PREF_MIN_ALIGNMENT_A_BYTES, align_w},
                   {CUBLASLT_MATMUL_PREF_MIN_ALIGNMENT_B_BYTES, align_x},
                   {CUBLASLT_MATMUL_PREF_MIN_ALIGNMENT_C_BYTES, align_y},
                   {CUBLASLT_MATMUL_PREF_MIN_ALIGNMENT_D_BYTES, align_y}};
    ATEX_RETURN_IF_ERROR(LtStatus(cublasLtMatmulPreferenceSetAttribute(raw_preference,
                                                                       CUBLASLT_MATMUL_PREF_MAX_WORKSPACE_BYTES,
                                                                       &workspace, sizeof(workspace)),
                                  "MAX_WORKSPACE_BYTES"));
    for (const auto& m : minimum) {
      ATEX_RETURN_IF_ERROR(
          LtStatus(cublasLtMatmulPreferenceSetAttribute(raw_preference, m.attribute, &m.bytes, sizeof(m.bytes)),
                   "MIN_ALIGNMENT"));
    }
    cublasLtMatmulHeuristicResult_t result{};
    int found = 0;
    const cublasStatus_t s =
        cublasLtMatmulAlgoGetHeuristic(handle_, raw_desc, a.get(), b.get(), c.get(), c.get(), raw_preference, 1,
                                       &result, &found);
    // The bias epilogue wants a 16-byte aligned bias on some algorithms and the heuristic
    // cannot be told the bias's alignment, so an unaligned bias falls back too.
    const bool usable = s == CUBLAS_STATUS_SUCCESS && found > 0 && result.state == CUBLAS_STATUS_SUCCESS &&
                        align_bias == 16;
    if (s != CUBLAS_STATUS_SUCCESS && s != CUBLAS_STATUS_NOT_SUPPORTED) {
      return LtStatus(s, "cublasLtMatmulAlgoGetHeuristic");
    }
    if (plans_.size() >= kMaxPlans) plans_.erase(plans_.begin());
    plans_.push_back({in, out, rows, ldx, ldy, allow_tf32, alignments, usable, result.algo});
    plan = &plans_.back();
  }
  if (!plan->found) return Status::Ok();
  const float one = 1.0f, zero = 0.0f;
  ATEX_RETURN_IF_ERROR(LtStatus(cublasLtMatmul(handle_, raw_desc, &one, w, a.get(), x, b.get(), &zero, y, c.get(), y,
                                               c.get(), &plan->algo, workspace_.data(), kWorkspaceBytes, stream),
                                "cublasLtMatmul"));
  *fused = true;
  return Status::Ok();
}

}  // namespace atex::cuda::deform_detail
