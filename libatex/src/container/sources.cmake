# Module 'container': the .atex format (format_spec/atex.md). Sources appended to
# libatex; tests registered in atex_container_tests().
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/asset_reader.cc
  ${CMAKE_CURRENT_LIST_DIR}/asset_writer.cc
  ${CMAKE_CURRENT_LIST_DIR}/attribute_stream.cc
  ${CMAKE_CURRENT_LIST_DIR}/chunks.cc
  ${CMAKE_CURRENT_LIST_DIR}/codecs.cc
  ${CMAKE_CURRENT_LIST_DIR}/draco_codec.cc
  ${CMAKE_CURRENT_LIST_DIR}/fingerprint.cc
  ${CMAKE_CURRENT_LIST_DIR}/half.cc
  ${CMAKE_CURRENT_LIST_DIR}/inspect.cc
  ${CMAKE_CURRENT_LIST_DIR}/layout.cc
  ${CMAKE_CURRENT_LIST_DIR}/read_back.cc
  ${CMAKE_CURRENT_LIST_DIR}/synthetic_asset.cc)
function(atex_container_tests)
  set(dir ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  atex_add_test(NAME container_test LABELS container hostile
    SOURCES ${dir}/codecs_test.cc ${dir}/half_test.cc ${dir}/attribute_stream_test.cc ${dir}/layout_test.cc
            ${dir}/chunks_test.cc ${dir}/roundtrip_test.cc ${dir}/compatibility_test.cc ${dir}/inspect_test.cc
            ${dir}/encode_cache_test.cc ${dir}/fingerprint_test.cc ${dir}/read_back_test.cc ${dir}/asset_compare.cc
    LIBS atex)
endfunction()
