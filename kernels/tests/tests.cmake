# Tests of the CUDA backend (included by kernels/CMakeLists.txt when ATEX_TESTS is on).
# One GoogleTest executable per source file, linked with atex_cuda, atex, cuBLAS and the
# test support library, labelled "cuda". Tests that need a GPU skip with a message when
# no device is present (ATEX_REQUIRE_CUDA_DEVICE() in gpu_test_support.h).
#
# Adding a test is one line:   atex_cuda_test(<name> <source file in kernels/tests>)

function(atex_cuda_test name source)
  atex_add_test(NAME ${name} SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/${source}
                LIBS atex_cuda atex CUDA::cudart CUDA::cublas LABELS cuda TIMEOUT 600)
  if(TARGET ${name})
    # Without a device every case skips: report the test as skipped, not passed.
    set_tests_properties(${name} PROPERTIES SKIP_REGULAR_EXPRESSION "\\[  SKIPPED \\]")
    # kernels/src for the engine headers (private to atex_cuda), kernels/tests for the helpers.
    target_include_directories(${name} PRIVATE ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/../src
                                               ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  endif()
endfunction()

atex_cuda_test(deform_parity_test deform_parity_test.cc)
atex_cuda_test(deform_engine_parity_test deform_engine_parity_test.cc)
atex_cuda_test(loss_parity_test loss_parity_test.cc)
atex_cuda_test(memory_limit_test memory_limit_test.cc)

# GPU benchmark of the deformation network and the loss (bench/bench_cuda_deform.cu). Built here
# because it needs atex_cuda; bench/CMakeLists.txt globs only bench_*.cc.
if(ATEX_BENCHMARKS AND benchmark_FOUND AND EXISTS ${PROJECT_SOURCE_DIR}/bench/bench_cuda_deform.cu)
  add_executable(bench_cuda_deform ${PROJECT_SOURCE_DIR}/bench/bench_cuda_deform.cu)
  target_link_libraries(bench_cuda_deform PRIVATE atex_cuda atex CUDA::cudart CUDA::cublas benchmark::benchmark)
  target_include_directories(bench_cuda_deform PRIVATE ${CMAKE_CURRENT_LIST_DIR}/../src)
  target_compile_options(bench_cuda_deform PRIVATE $<$<COMPILE_LANGUAGE:CUDA>:--expt-relaxed-constexpr>)
  set_target_properties(bench_cuda_deform PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/bench)
endif()

# Rasteriser and whole-backend parity with the CPU reference; they reuse the render
# module's random scenes (libatex/src/render/render_test_util.cc).
# The forward rasteriser's texture sample against the reference functions: CPU only (runs in CI).
atex_cuda_test(forward_texture_test forward_texture_test.cc)
atex_cuda_test(render_parity_test render_parity_test.cc)
atex_cuda_test(backend_parity_test backend_parity_test.cc)
atex_cuda_test(keyed_load_test keyed_load_test.cc)
# Two GPUs through NCCL (skips without NCCL or with one GPU).
atex_cuda_test(nccl_data_parallel_test nccl_data_parallel_test.cc)
foreach(t render_parity_test backend_parity_test keyed_load_test nccl_data_parallel_test)
  if(TARGET ${t})
    target_sources(${t} PRIVATE ${PROJECT_SOURCE_DIR}/libatex/src/render/render_test_util.cc)
  endif()
endforeach()
