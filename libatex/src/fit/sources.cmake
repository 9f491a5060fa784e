# Module 'fit': the budget fitter (atex/fit.h, docs/fit.md). Sources appended to
# libatex; tests registered in atex_fit_tests().
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/apply_plan.cc
  ${CMAKE_CURRENT_LIST_DIR}/budget.cc
  ${CMAKE_CURRENT_LIST_DIR}/candidate_map.cc
  ${CMAKE_CURRENT_LIST_DIR}/count_search.cc
  ${CMAKE_CURRENT_LIST_DIR}/byte_size.cc
  ${CMAKE_CURRENT_LIST_DIR}/candidate_evaluator.cc
  ${CMAKE_CURRENT_LIST_DIR}/cpu_probes.cc
  ${CMAKE_CURRENT_LIST_DIR}/incremental_base.cc
  ${CMAKE_CURRENT_LIST_DIR}/incremental_probes.cc
  ${CMAKE_CURRENT_LIST_DIR}/levers.cc
  ${CMAKE_CURRENT_LIST_DIR}/measure.cc
  ${CMAKE_CURRENT_LIST_DIR}/moves.cc
  ${CMAKE_CURRENT_LIST_DIR}/plan.cc
  ${CMAKE_CURRENT_LIST_DIR}/preparation_pool.cc
  ${CMAKE_CURRENT_LIST_DIR}/probes.cc
  ${CMAKE_CURRENT_LIST_DIR}/proposals.cc
  ${CMAKE_CURRENT_LIST_DIR}/refill.cc
  ${CMAKE_CURRENT_LIST_DIR}/report.cc
  ${CMAKE_CURRENT_LIST_DIR}/run.cc
  ${CMAKE_CURRENT_LIST_DIR}/texture_shrink.cc
  ${CMAKE_CURRENT_LIST_DIR}/tile_composite.cc)
function(atex_fit_tests)
  set(dir ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  atex_add_test(NAME fit_test LABELS fit LIBS atex
    SOURCES ${dir}/fit_test.cc ${dir}/fit_search_test.cc ${dir}/fit_levers_test.cc ${dir}/fit_run_test.cc ${dir}/texture_shrink_test.cc ${dir}/fit_time_windows_test.cc ${dir}/refill_test.cc ${dir}/preparation_pool_test.cc)
  atex_add_test(NAME cpu_probes_test LABELS fit SOURCES ${dir}/cpu_probes_test.cc LIBS atex)
  atex_add_test(NAME incremental_probes_test LABELS fit SOURCES ${dir}/incremental_probes_test.cc
                ${dir}/incremental_full_test.cc LIBS atex)
  # The committed lego sample against the real tiny lego images (a minute or two on 2 cores).
  atex_add_test(NAME fit_lego_test LABELS fit SOURCES ${dir}/fit_lego_test.cc LIBS atex)
endfunction()
