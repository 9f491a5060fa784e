# Cross-module tests of the .atex container (format_spec/atex.md): frozen golden
# files, hostile input (truncations, bit flips), and the command line.
set(ATEX_CONTAINER_TEST_DIR ${CMAKE_CURRENT_LIST_DIR})
set(ATEX_CONTAINER_TEST_COMMON
  ${ATEX_CONTAINER_TEST_DIR}/golden_assets.cc
  ${PROJECT_SOURCE_DIR}/libatex/src/container/asset_compare.cc)

atex_add_test(NAME container_golden_test LABELS container hostile
  SOURCES ${ATEX_CONTAINER_TEST_DIR}/golden_test.cc ${ATEX_CONTAINER_TEST_COMMON}
  LIBS atex ${ATEX_ZSTD_TARGET})
atex_add_test(NAME container_hostile_test LABELS container hostile
  SOURCES ${ATEX_CONTAINER_TEST_DIR}/hostile_input_test.cc ${ATEX_CONTAINER_TEST_COMMON}
  LIBS atex)
atex_add_test(NAME container_cli_test LABELS container
  SOURCES ${ATEX_CONTAINER_TEST_DIR}/cli_test.cc LIBS atex)
set_property(TEST container_cli_test APPEND PROPERTY ENVIRONMENT "ATEX_CLI=$<TARGET_FILE:atex_cli>")
add_dependencies(container_cli_test atex_cli)

# Rewrites the frozen files; not a test (see write_golden.cc).
add_executable(atex_write_golden ${ATEX_CONTAINER_TEST_DIR}/write_golden.cc ${ATEX_CONTAINER_TEST_DIR}/golden_assets.cc)
target_link_libraries(atex_write_golden PRIVATE atex atex_build_flags)
target_include_directories(atex_write_golden PRIVATE ${PROJECT_SOURCE_DIR}/libatex/src)
