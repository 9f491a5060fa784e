# The command line's robustness (issue 24): the one strict option parser (tools/cli_parse.cc)
# as a unit, and every command end to end: bad values refused before work, outputs never
# clobbered, JSON errors under --json, training configs refused before training.
atex_add_test(NAME cli_parse_test LABELS cli
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/cli_parse_test.cc ${PROJECT_SOURCE_DIR}/tools/cli_parse.cc
  LIBS atex CLI11::CLI11)
if(TARGET cli_parse_test)
  target_include_directories(cli_parse_test PRIVATE ${PROJECT_SOURCE_DIR}/tools)
endif()
atex_add_test(NAME cli_robustness_test LABELS cli
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/cli_robustness_test.cc LIBS atex TIMEOUT 600)
if(TARGET cli_robustness_test)
  set_property(TEST cli_robustness_test APPEND PROPERTY ENVIRONMENT "ATEX_CLI=$<TARGET_FILE:atex_cli>")
  add_dependencies(cli_robustness_test atex_cli)
endif()
# The dataset kinds users hold (issue 21): nerfstudio transforms.json, COLMAP models and N3DV videos,
# written by the test, trained a few CPU steps and evaluated through the binary.
atex_add_test(NAME cli_datasets_test LABELS cli
  SOURCES ${CMAKE_CURRENT_LIST_DIR}/cli_datasets_test.cc LIBS atex TIMEOUT 600)
if(TARGET cli_datasets_test)
  set_property(TEST cli_datasets_test APPEND PROPERTY ENVIRONMENT "ATEX_CLI=$<TARGET_FILE:atex_cli>")
  add_dependencies(cli_datasets_test atex_cli)
  find_program(ATEX_FFMPEG_EXECUTABLE ffmpeg)  # encodes the N3DV test videos (Debian package ffmpeg)
  set(ffmpeg "${ATEX_FFMPEG_EXECUTABLE}")
  if(NOT ATEX_FFMPEG_EXECUTABLE)
    set(ffmpeg "")
  endif()
  target_compile_definitions(cli_datasets_test PRIVATE ATEX_FFMPEG_EXECUTABLE="${ffmpeg}")
endif()
