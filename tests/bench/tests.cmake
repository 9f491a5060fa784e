# The experiment harness of issue 9 (bench/run_matrix.py, bench/paired_bootstrap.py,
# bench/charts.py), tested without a GPU:
#   bench_run_matrix     --dry-run on every bench/configs/*.json; resumability, failure rows,
#                        --deadline + checkpoint resume and the paired bootstrap against a fake
#                        atex (tests/bench/fake_atex.py)
#   bench_lego_matrix    the real atex (CPU backend) on bench/configs/lego_cpu.json, end to end
#   bench_charts         charts.py on bench/testdata/example_results.csv: four valid PNGs
#   bench_function_length  bench/function_length.py (the function and file length check of
#                        bench/format_check.sh) on synthetic sources of known function lengths
# Needs a Python 3 interpreter; the charts test needs matplotlib (Debian python3-matplotlib) and
# is skipped (exit 77) without it.
find_package(Python3 COMPONENTS Interpreter)
if(NOT Python3_Interpreter_FOUND)
  message(STATUS "atex: no Python 3 interpreter: the bench harness tests are not registered")
  return()
endif()
set(ATEX_BENCH_TEST_DIR ${CMAKE_CURRENT_LIST_DIR})

add_test(NAME bench_run_matrix
  COMMAND ${Python3_EXECUTABLE} ${ATEX_BENCH_TEST_DIR}/test_run_matrix.py
          --source-dir ${PROJECT_SOURCE_DIR} --work-dir ${PROJECT_BINARY_DIR}/bench_run_matrix)
set_tests_properties(bench_run_matrix PROPERTIES TIMEOUT 300 LABELS bench)

add_test(NAME bench_lego_matrix
  COMMAND ${Python3_EXECUTABLE} ${ATEX_BENCH_TEST_DIR}/test_lego_matrix.py
          --atex $<TARGET_FILE:atex_cli> --out ${PROJECT_BINARY_DIR}/bench_lego_matrix)
set_tests_properties(bench_lego_matrix PROPERTIES TIMEOUT 600 LABELS bench SKIP_RETURN_CODE 77
  ENVIRONMENT "ATEX_DATA_DIR_DEFAULT=${ATEX_DATA_DIR};OMP_WAIT_POLICY=PASSIVE")

add_test(NAME bench_function_length
  COMMAND ${Python3_EXECUTABLE} ${ATEX_BENCH_TEST_DIR}/test_function_length.py
          --work-dir ${PROJECT_BINARY_DIR}/bench_function_length)
set_tests_properties(bench_function_length PROPERTIES TIMEOUT 60 LABELS bench)

# The charts need matplotlib: use the first of the found interpreter and /usr/bin/python3 that
# has it (a pyenv/venv python3 first on PATH often lacks it); ATEX_CHARTS_PYTHON overrides.
set(ATEX_CHARTS_PYTHON "" CACHE FILEPATH "Python 3 with matplotlib for the bench_charts test (empty: search)")
set(atex_charts_python "${ATEX_CHARTS_PYTHON}")
if(NOT atex_charts_python)
  set(atex_charts_python ${Python3_EXECUTABLE})
  foreach(candidate ${Python3_EXECUTABLE} /usr/bin/python3)
    if(EXISTS ${candidate})
      execute_process(COMMAND ${candidate} -c "import matplotlib" RESULT_VARIABLE atex_no_mpl OUTPUT_QUIET ERROR_QUIET)
      if(atex_no_mpl EQUAL 0)
        set(atex_charts_python ${candidate})
        break()
      endif()
    endif()
  endforeach()
endif()
add_test(NAME bench_charts
  COMMAND ${atex_charts_python} ${ATEX_BENCH_TEST_DIR}/test_charts.py
          --csv ${PROJECT_SOURCE_DIR}/bench/testdata/example_results.csv
          --charts ${PROJECT_SOURCE_DIR}/bench/charts.py --out ${PROJECT_BINARY_DIR}/bench_charts)
set_tests_properties(bench_charts PROPERTIES TIMEOUT 120 LABELS bench SKIP_RETURN_CODE 77)
