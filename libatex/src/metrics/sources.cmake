# Module 'metrics': PSNR, SSIM, DSSIM and the training loss with its gradient.
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/metrics.cc
  ${CMAKE_CURRENT_LIST_DIR}/loss.cc
  ${CMAKE_CURRENT_LIST_DIR}/dynamic_region.cc)
function(atex_metrics_tests)
  atex_add_test(NAME metrics_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/metrics_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/loss_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/dynamic_region_test.cc
    LIBS atex nlohmann_json::nlohmann_json
    TIMEOUT 300)
endfunction()
