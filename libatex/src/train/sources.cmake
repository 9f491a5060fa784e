# Module 'train': the training loop, schedules, host-side decisions, the Backend
# interface and its CPU implementation.
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/config.cc
  ${CMAKE_CURRENT_LIST_DIR}/config_check.cc
  ${CMAKE_CURRENT_LIST_DIR}/schedule.cc
  ${CMAKE_CURRENT_LIST_DIR}/densify.cc
  ${CMAKE_CURRENT_LIST_DIR}/texture_growth.cc
  ${CMAKE_CURRENT_LIST_DIR}/cpu_backend.cc
  ${CMAKE_CURRENT_LIST_DIR}/checkpoint.cc
  ${CMAKE_CURRENT_LIST_DIR}/trainer.cc
  ${CMAKE_CURRENT_LIST_DIR}/training_records.cc
  ${CMAKE_CURRENT_LIST_DIR}/training_step.cc
  ${CMAKE_CURRENT_LIST_DIR}/communicator.cc
  ${CMAKE_CURRENT_LIST_DIR}/data_parallel.cc
  ${CMAKE_CURRENT_LIST_DIR}/tcp_rendezvous.cc
  ${CMAKE_CURRENT_LIST_DIR}/stage1_init.cc
  ${CMAKE_CURRENT_LIST_DIR}/model_state.cc
  ${CMAKE_CURRENT_LIST_DIR}/evaluate.cc
  ${CMAKE_CURRENT_LIST_DIR}/colour_correction.cc
  ${CMAKE_CURRENT_LIST_DIR}/camera_colours.cc
  ${CMAKE_CURRENT_LIST_DIR}/report.cc)
function(atex_train_tests)
  set(dir ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  atex_add_test(NAME train_test LIBS atex SOURCES
    ${dir}/checkpoint_test.cc ${dir}/model_state_test.cc ${dir}/config_test.cc ${dir}/config_check_test.cc
    ${dir}/densify_test.cc
    ${dir}/schedule_test.cc ${dir}/texture_growth_test.cc
    ${dir}/colour_correction_test.cc ${dir}/camera_colours_test.cc ${PROJECT_SOURCE_DIR}/libatex/src/render/render_test_util.cc)
  # Collectives (ranks as threads) and the data-parallel loop on a synthetic scene: two ranks
  # with half the views each against one rank with all of them.
  atex_add_test(NAME train_communicator_test LIBS atex SOURCES ${dir}/communicator_test.cc
    ${dir}/tcp_rendezvous_test.cc)
  atex_add_test(NAME train_data_parallel_test LIBS atex SOURCES ${dir}/data_parallel_test.cc)
  # The loop on the real tiny lego (CPU backend): a few minutes, its own executable so that
  # CTest runs it beside the others.
  atex_add_test(NAME train_lego_test LIBS atex SOURCES ${dir}/trainer_test.cc TIMEOUT 2400)
  # The loop on a synthetic moving ball (no data needed): resume, rollback, time limit,
  # phase order, growth.
  atex_add_test(NAME train_synthetic_test LIBS atex SOURCES ${dir}/trainer_synthetic_test.cc)
endfunction()
