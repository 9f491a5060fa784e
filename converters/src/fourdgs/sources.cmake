# Converter 'fourdgs': 4DGaussians checkpoints (point_cloud.ply + deformation.pth)
# read without Python: a safe allow-list unpickler, the torch.save zip layout,
# and the mapping of deform_network's state_dict onto atex's DeformationField.
list(APPEND ATEX_CONVERTER_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/torch_pickle.cc
  ${CMAKE_CURRENT_LIST_DIR}/torch_checkpoint.cc
  ${CMAKE_CURRENT_LIST_DIR}/fourdgs_field.cc
  ${CMAKE_CURRENT_LIST_DIR}/fourdgs_import.cc)
function(atex_converter_fourdgs_tests)
  # Labelled hostile: tests/sanitize.sh runs it under ASan + UBSan (truncated, forged and
  # refused pickles and archives).
  atex_add_test(NAME converter_fourdgs_test LABELS hostile
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/torch_test_util.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/torch_pickle_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/torch_checkpoint_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/fourdgs_import_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/fourdgs_fixture_test.cc
    LIBS atex_converters)
  target_include_directories(converter_fourdgs_test PRIVATE ${PROJECT_SOURCE_DIR}/converters/src)
endfunction()
