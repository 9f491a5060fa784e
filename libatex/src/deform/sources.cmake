# Module 'deform': the HexPlane + MLP deformation field (forward, backward,
# initialisation, regularisers). Tests registered in atex_deform_tests().
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/deform_field.cc
  ${CMAKE_CURRENT_LIST_DIR}/deform_forward.cc
  ${CMAKE_CURRENT_LIST_DIR}/deform_backward.cc
  ${CMAKE_CURRENT_LIST_DIR}/deform_regularizer.cc)
function(atex_deform_tests)
  atex_add_test(NAME deform_test
    SOURCES ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/hexplane_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/deform_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/deform_gradient_test.cc
            ${CMAKE_CURRENT_FUNCTION_LIST_DIR}/deform_test_util.cc
    LIBS atex)
endfunction()
