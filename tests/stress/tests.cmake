# Stress suite at CPU scale (issue 9): degenerate content, numerical stress, long
# sequences, fast motion, sparse views, tight budgets and NaN injection through the
# reference renderer, the container and the CPU training backend. Each case's outcome
# goes into ${PROJECT_BINARY_DIR}/tests/stress/stress_table.{json,md}; the test fails
# only on a crash, an uncaught NaN or an error without a message. A summary is kept
# in bench/results/stress_cpu.md.
atex_add_test(NAME stress_cpu_test LABELS stress
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/stress_test.cc
  LIBS atex
  TIMEOUT 300)
# Tiny scenes gain nothing from threads, and libgomp's spinning barriers made the CPU
# backend ~40x slower on a loaded 2-core machine (many small parallel regions per step):
# let waiting threads sleep. Results do not depend on the thread count.
set_property(TEST stress_cpu_test APPEND PROPERTY ENVIRONMENT "OMP_WAIT_POLICY=PASSIVE")
