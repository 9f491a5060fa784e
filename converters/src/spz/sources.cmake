# Converter 'spz': Niantic SPZ (read v1-v4, write v3 gzip and v4 zstd streams).
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/spz.cc
  ${CMAKE_CURRENT_LIST_DIR}/spz_compress.cc
  ${CMAKE_CURRENT_LIST_DIR}/spz_container.cc
  ${CMAKE_CURRENT_LIST_DIR}/spz_quantize.cc)
function(atex_converter_spz_tests)
  atex_add_test(NAME converter_spz_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/spz_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/spz_handbuilt_test.cc
    LIBS atex_converters ${ATEX_ZSTD_TARGET} ZLIB::ZLIB)
  target_include_directories(converter_spz_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
  # Independent decoder check: the reference SPZ library (npm @adobe/spz, the WASM
  # build of nianticlabs/spz) decodes files our writer produced (tests/spz_node).
  atex_add_test(NAME converter_spz_node_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/spz_node_test.cc
    LIBS atex_converters)
  target_include_directories(converter_spz_node_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
  set_tests_properties(converter_spz_node_test PROPERTIES LABELS "external;node")
endfunction()
