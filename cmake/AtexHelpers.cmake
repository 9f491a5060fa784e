# Small helpers shared by every folder's CMakeLists.

function(atex_report_optional found what)
  if(${found})
    message(STATUS "atex: with ${what}")
  else()
    message(STATUS "atex: WITHOUT ${what} (package not found; that feature reports 'unsupported')")
  endif()
endfunction()

# atex_add_test(NAME <name> SOURCES <files...> [LIBS <targets...>] [LABELS <labels...>] [TIMEOUT <s>])
# One GoogleTest executable registered as one CTest test. Tests read real data from
# ATEX_DATA_DIR (environment) which defaults to the configured ../shared/data.
function(atex_add_test)
  cmake_parse_arguments(T "" "NAME;TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  if(NOT ATEX_TESTS)
    return()
  endif()
  add_executable(${T_NAME} ${T_SOURCES})
  target_link_libraries(${T_NAME} PRIVATE ${T_LIBS} atex_test_support GTest::gtest GTest::gtest_main atex_build_flags)
  add_test(NAME ${T_NAME} COMMAND ${T_NAME})
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 900)
  endif()
  set_tests_properties(${T_NAME} PROPERTIES TIMEOUT ${T_TIMEOUT}
    ENVIRONMENT "ATEX_DATA_DIR_DEFAULT=${ATEX_DATA_DIR};ATEX_SOURCE_DIR=${PROJECT_SOURCE_DIR};ATEX_BINARY_DIR=${PROJECT_BINARY_DIR}")
  if(T_LABELS)
    set_tests_properties(${T_NAME} PROPERTIES LABELS "${T_LABELS}")
  endif()
endfunction()
