# libFuzzer targets. Every tests/fuzz/fuzz_<reader>.cc becomes the executable
# fuzz_<reader> (linked with atex and atex_converters and -fsanitize=fuzzer) when
# ATEX_FUZZ is ON; its seed corpus is tests/fuzz/corpus/<reader>/. They are built
# and run briefly by tests/sanitize.sh; `atex_fuzz_targets` builds them all.
if(ATEX_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(WARNING "ATEX_FUZZ needs clang (CC=clang CXX=clang++): fuzz targets not built")
  else()
    file(GLOB ATEX_FUZZ_SOURCES CONFIGURE_DEPENDS ${CMAKE_CURRENT_LIST_DIR}/fuzz_*.cc)
    set(ATEX_FUZZ_TARGETS "")
    foreach(source ${ATEX_FUZZ_SOURCES})
      get_filename_component(name ${source} NAME_WE)
      add_executable(${name} ${source})
      target_link_libraries(${name} PRIVATE atex atex_converters atex_build_flags)
      target_link_options(${name} PRIVATE -fsanitize=fuzzer)
      set_target_properties(${name} PROPERTIES RUNTIME_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/fuzz)
      list(APPEND ATEX_FUZZ_TARGETS ${name})
    endforeach()
    add_custom_target(atex_fuzz_targets DEPENDS ${ATEX_FUZZ_TARGETS})
  endif()
endif()
