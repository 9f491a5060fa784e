# Converter 'drc': Google Draco point-cloud export (positions + optional attributes).
list(APPEND ATEX_CONVERTER_SOURCES ${CMAKE_CURRENT_LIST_DIR}/drc.cc)
function(atex_converter_drc_tests)
  if(NOT draco_FOUND)
    return()
  endif()
  atex_add_test(NAME converter_drc_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/drc_test.cc
    LIBS atex_converters)
  target_include_directories(converter_drc_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
endfunction()
