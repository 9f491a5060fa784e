# Converter 'exr': the texture pool as an OpenEXR half-float RGBA atlas + JSON sidecar.
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/atlas_layout.cc
  ${CMAKE_CURRENT_LIST_DIR}/exr_atlas.cc)
if(OpenEXR_FOUND)
  list(APPEND ATEX_CONVERTER_SOURCES ${CMAKE_CURRENT_LIST_DIR}/exr_image.cc)
endif()
function(atex_converter_exr_tests)
  if(NOT OpenEXR_FOUND)
    return()
  endif()
  atex_add_test(NAME converter_exr_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/exr_atlas_test.cc
    LIBS atex_converters OpenEXR::OpenEXR)
  target_include_directories(converter_exr_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
endfunction()
