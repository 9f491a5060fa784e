# The installed C++ library: cmake --install into build/install-test/prefix, then a tiny
# consumer project built against it with find_package(atex) and with pkg-config, run on the
# bundled sample (reads it, renders a view).
add_test(NAME atex_install_consumer COMMAND ${CMAKE_CURRENT_LIST_DIR}/run_consumer.sh ${PROJECT_BINARY_DIR})
set_tests_properties(atex_install_consumer PROPERTIES TIMEOUT 900 LABELS install
  ENVIRONMENT "CXX=${CMAKE_CXX_COMPILER}")
