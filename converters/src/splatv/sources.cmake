# Converter 'splatv': splaTV (.splatv) export with closed-form motion fitted to the
# deformation field, and a reader with the viewer's rules.
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/motion_fit.cc
  ${CMAKE_CURRENT_LIST_DIR}/splatv_format.cc
  ${CMAKE_CURRENT_LIST_DIR}/splatv_camera.cc
  ${CMAKE_CURRENT_LIST_DIR}/splatv_export.cc)
function(atex_converter_splatv_tests)
  atex_add_test(NAME converter_splatv_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/splatv_test.cc
            ${PROJECT_SOURCE_DIR}/converters/src/gltf/gltf_test_scene.cc
    LIBS atex_converters
    LABELS hostile
    TIMEOUT 300)
  target_include_directories(converter_splatv_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
endfunction()
