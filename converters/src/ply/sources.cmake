# Converter 'ply': INRIA 3DGS PLY files (read binary LE/BE + ASCII, write binary LE).
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/ply_header.cc
  ${CMAKE_CURRENT_LIST_DIR}/ply_read.cc
  ${CMAKE_CURRENT_LIST_DIR}/ply_compressed.cc
  ${CMAKE_CURRENT_LIST_DIR}/ply_write.cc)
function(atex_converter_ply_tests)
  atex_add_test(NAME converter_ply_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/ply_test.cc
    LIBS atex_converters)
  target_include_directories(converter_ply_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
endfunction()
