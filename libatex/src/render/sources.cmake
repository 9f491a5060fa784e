# Module 'render': the CPU reference rasteriser (forward, backward, texture pools).
# The per-element mathematics it shares with the CUDA backend is header-only in
# libatex/include/atex/detail/ (projection.h, sh.h, texture.h, composite.h, ...).
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/validate.cc
  ${CMAKE_CURRENT_LIST_DIR}/project.cc
  ${CMAKE_CURRENT_LIST_DIR}/rasterize_forward.cc
  ${CMAKE_CURRENT_LIST_DIR}/rasterize_backward.cc
  ${CMAKE_CURRENT_LIST_DIR}/render.cc
  ${CMAKE_CURRENT_LIST_DIR}/textures.cc)

function(atex_render_tests)
  set(dir ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  atex_add_test(NAME render_test TIMEOUT 600 LIBS atex SOURCES
    ${dir}/render_test_util.cc
    ${dir}/detail_test.cc
    ${dir}/render_forward_test.cc
    ${dir}/render_validation_test.cc
    ${dir}/render_gradient_test.cc
    ${dir}/texture_test.cc)

  # Compile-only check that atex/detail/*.h builds as CUDA device code. Needs nvcc,
  # not a GPU; registered only where nvcc exists (the CUDA build compiles the same
  # headers in kernels/ anyway).
  if(ATEX_TESTS)
    if(CMAKE_CUDA_COMPILER)
      set(nvcc ${CMAKE_CUDA_COMPILER})
    else()
      find_program(ATEX_NVCC_FOR_CHECKS nvcc PATHS /usr/local/cuda/bin)
      set(nvcc ${ATEX_NVCC_FOR_CHECKS})
    endif()
    if(nvcc)
      add_test(NAME render_detail_nvcc_check
        COMMAND ${nvcc} -arch=sm_90 -std=c++20 --expt-relaxed-constexpr -Werror all-warnings
                -I${PROJECT_SOURCE_DIR}/libatex/include -c ${dir}/detail_nvcc_check.cu
                -o ${PROJECT_BINARY_DIR}/detail_nvcc_check.o)
      set_tests_properties(render_detail_nvcc_check PROPERTIES TIMEOUT 600 LABELS "compile")
    endif()
  endif()
endfunction()
