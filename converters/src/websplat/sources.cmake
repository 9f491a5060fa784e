# Converter 'websplat': the web viewers' static formats .splat (antimatter15) and
# .ksplat (mkkellogg GaussianSplats3D); SOG lives in ../sog, compressed PLY in ../ply.
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/splat_read.cc
  ${CMAKE_CURRENT_LIST_DIR}/ksplat_read.cc)
function(atex_converter_websplat_tests)
  atex_add_test(NAME converter_websplat_test LABELS hostile
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/websplat_test.cc
    LIBS atex_converters)
  target_include_directories(converter_websplat_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
  # Real files from third-party writers (npm, tests/splat_transform) against splat-transform's decoding.
  atex_add_test(NAME converter_websplat_real_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/websplat_real_test.cc
    LIBS atex_converters)
  target_include_directories(converter_websplat_real_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
  set_tests_properties(converter_websplat_real_test PROPERTIES LABELS "external;node" TIMEOUT 600)
endfunction()
