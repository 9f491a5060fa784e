# Module 'core': status, model validation, metadata JSON, files, checksums.
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/status.cc)
function(atex_core_tests)
  atex_add_test(NAME core_test SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/status_test.cc LIBS atex)
endfunction()
