# Converter 'gltf': glTF 2.0 export (KHR_gaussian_splatting + ATEX_gaussian_textures +
# ATEX_gaussian_deformation, optional EXT_meshopt_compression, KHR_mesh_quantization) and import through tinygltf.
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/gltf_axes.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_writer.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_export.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_container.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_accessors.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_import.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_import_base.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_import_extensions.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_import_scene.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_spz.cc
  ${CMAKE_CURRENT_LIST_DIR}/gltf_quantize.cc
  ${CMAKE_CURRENT_LIST_DIR}/meshopt_codec.cc
  ${CMAKE_CURRENT_LIST_DIR}/sh_rotation.cc
  ${CMAKE_CURRENT_LIST_DIR}/tinygltf_impl.cc)
function(atex_converter_gltf_tests)
  atex_add_test(NAME converter_gltf_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/gltf_test_scene.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/gltf_export_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/gltf_import_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/gltf_hostile_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/gltf_spz_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/gltf_quantize_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/gltf_khr_spec_test.cc
    LIBS atex_converters
    LABELS hostile
    TIMEOUT 300)
  target_include_directories(converter_gltf_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
  if(TinyGLTF_FOUND)
    target_compile_definitions(converter_gltf_test PRIVATE ATEX_HAVE_TINYGLTF=1)
  endif()
  if(meshoptimizer_FOUND)
    target_compile_definitions(converter_gltf_test PRIVATE ATEX_HAVE_MESHOPT=1)
  endif()
endfunction()
