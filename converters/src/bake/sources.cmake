# Converter helper 'bake': textured Gaussians -> plain Gaussians for players without textures
# (used by the glTF export's bake_textures option).
list(APPEND ATEX_CONVERTER_SOURCES ${CMAKE_CURRENT_LIST_DIR}/texture_bake.cc)
function(atex_converter_bake_tests)
  atex_add_test(NAME converter_bake_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/texture_bake_test.cc
    LIBS atex_converters
    TIMEOUT 300)
  if(TinyGLTF_FOUND)
    target_compile_definitions(converter_bake_test PRIVATE ATEX_HAVE_TINYGLTF=1)
  endif()
endfunction()
