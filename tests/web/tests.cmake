# Third-party checks of our exports, run by CTest (installed by tests/web/install.sh):
#   web_gltf_validator  Khronos glTF-Validator (npm gltf-validator) on every export flavour
#   web_babylon_render  our .glb in unmodified Babylon.js in headless Chromium, compared with
#                       libatex's reference renderer (synthetic "F" and real garden points);
#                       the lego sample's cameras' up direction must come out as +y in
#                       Babylon's world (the golden "upright" check); the lego's quantised
#                       export (--quantize, and with --meshopt) against the plain one's picture
#   web_splatv_reader   our .splatv read by a re-implementation of splaTV's reader and shader
#   web_playcanvas_render  our .glb and .ply in the unmodified PlayCanvas engine (npm playcanvas)
#   web_spark_render    our .ply and .spz in three.js with Spark (npm three, @sparkjsdev/spark);
#                       both player checks (player_render.mjs, pages in players/): the "F" upright,
#                       not mirrored, per-colour IoU; the lego sample upright, PSNR against our render
#                       (the fixture's optional player_model_vN scenes, an external trained model
#                       at chosen test views, are drawn by the three players only when it was built
#                       with ATEX_PLAYER_MODEL: bench/web_players_model.sh, not CTest)
#   web_cli_export      `atex export` / `atex import` end to end (no node needed)
#   web_view_cli        `atex view` on the command line (no node needed)
#   web_view_page       the page of `atex view` in headless Chromium from file:// (view_page.mjs)
# A missing node, npm package or chromium fails these tests when ATEX_REQUIRE_DATA=1 (CI)
# and skips them (exit code 77) otherwise.
set(ATEX_WEB_DIR ${CMAKE_CURRENT_LIST_DIR})
set(ATEX_WEB_OUT ${PROJECT_BINARY_DIR}/web_fixture)

add_executable(atex_web_fixture ${ATEX_WEB_DIR}/web_fixture.cc ${ATEX_WEB_DIR}/web_fixture_player.cc
  ${PROJECT_SOURCE_DIR}/converters/src/gltf/gltf_test_scene.cc)
target_include_directories(atex_web_fixture PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
target_link_libraries(atex_web_fixture PRIVATE atex_converters atex atex_build_flags)

add_test(NAME web_fixture COMMAND atex_web_fixture ${ATEX_WEB_OUT})
set_tests_properties(web_fixture PROPERTIES FIXTURES_SETUP atex_web TIMEOUT 300
  ENVIRONMENT "ATEX_DATA_DIR_DEFAULT=${ATEX_DATA_DIR};ATEX_SOURCE_DIR=${PROJECT_SOURCE_DIR}")

add_test(NAME web_cli_export COMMAND bash ${ATEX_WEB_DIR}/cli_export.sh $<TARGET_FILE:atex_cli> ${ATEX_WEB_OUT})
set_tests_properties(web_cli_export PROPERTIES FIXTURES_REQUIRED atex_web TIMEOUT 300)

foreach(check gltf_validator babylon_render splatv_reader)
  add_test(NAME web_${check} COMMAND bash ${ATEX_WEB_DIR}/run_node.sh ${ATEX_WEB_DIR}/${check}.mjs ${ATEX_WEB_OUT})
  set_tests_properties(web_${check} PROPERTIES FIXTURES_REQUIRED atex_web SKIP_RETURN_CODE 77 TIMEOUT 180
    LABELS web ENVIRONMENT "ATEX_SOURCE_DIR=${PROJECT_SOURCE_DIR}")
endforeach()

# Babylon.js draws up to twelve scenes, six of them the 91,490-Gaussian lego (about 25 s each on the
# CPU machine's software WebGL2): plain and with 3DGS's blur, quantised with and without meshopt,
# baked with either blur.
set_tests_properties(web_babylon_render PROPERTIES TIMEOUT 600)

# Third-party players in headless Chromium (player_render.mjs PLAYER FIXTURE_DIR); Spark is slow
# on software WebGL2 (about a minute per lego picture on the CPU machine).
foreach(player playcanvas spark)
  add_test(NAME web_${player}_render
    COMMAND bash ${ATEX_WEB_DIR}/run_node.sh ${ATEX_WEB_DIR}/player_render.mjs ${player} ${ATEX_WEB_OUT})
  set_tests_properties(web_${player}_render PROPERTIES FIXTURES_REQUIRED atex_web SKIP_RETURN_CODE 77 TIMEOUT 600
    LABELS web ENVIRONMENT "ATEX_SOURCE_DIR=${PROJECT_SOURCE_DIR}")
endforeach()

# `atex view`: the command line (no browser needed), then the lego sample's page in headless
# Chromium from file:// against `atex render` of its opening camera at three times.
add_test(NAME web_view_cli COMMAND bash ${ATEX_WEB_DIR}/view_cli.sh $<TARGET_FILE:atex_cli> ${PROJECT_SOURCE_DIR})
set_tests_properties(web_view_cli PROPERTIES TIMEOUT 300)
add_test(NAME web_view_page
  COMMAND bash ${ATEX_WEB_DIR}/view_page.sh $<TARGET_FILE:atex_cli> ${PROJECT_SOURCE_DIR} ${PROJECT_BINARY_DIR}/web_view)
set_tests_properties(web_view_page PROPERTIES SKIP_RETURN_CODE 77 TIMEOUT 300 LABELS web)
