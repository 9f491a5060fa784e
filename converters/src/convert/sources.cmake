# Converter 'convert': `atex convert` dispatch (format by extension, 4DGaussians
# folders), per-frame export, and the checks shared by every writer. The tests read
# the 4DGaussians fixture in tests/fixtures/fourdgs.
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/convert.cc
  ${CMAKE_CURRENT_LIST_DIR}/convert_frames.cc
  ${CMAKE_CURRENT_LIST_DIR}/convert_names.cc
  ${CMAKE_CURRENT_LIST_DIR}/gaussian_checks.cc
  ${CMAKE_CURRENT_LIST_DIR}/world_turn.cc)
function(atex_converter_convert_tests)
  atex_add_test(NAME converter_convert_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/convert_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/frames_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/fourdgs_convert_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/world_turn_test.cc
    LIBS atex_converters)
  target_include_directories(converter_convert_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
  # The test also runs the `atex convert` command line.
  add_dependencies(converter_convert_test atex_cli)
endfunction()
