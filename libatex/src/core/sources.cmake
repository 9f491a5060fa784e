# Module 'core': status, model validation, metadata JSON, files, checksums.
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/status.cc
  ${CMAKE_CURRENT_LIST_DIR}/crc32c.cc
  ${CMAKE_CURRENT_LIST_DIR}/file_io.cc
  ${CMAKE_CURRENT_LIST_DIR}/metadata_json.cc
  ${CMAKE_CURRENT_LIST_DIR}/world_up.cc
  ${CMAKE_CURRENT_LIST_DIR}/model_validate.cc)
function(atex_core_tests)
  set(dir ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  atex_add_test(NAME core_test LABELS core hostile
    SOURCES ${dir}/status_test.cc ${dir}/crc32c_test.cc ${dir}/file_io_test.cc ${dir}/metadata_json_test.cc ${dir}/world_up_test.cc
            ${dir}/model_validate_test.cc
    LIBS atex)
endfunction()
