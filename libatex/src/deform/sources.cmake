# Module 'deform': sources appended to libatex; tests registered in atex_deform_tests().
list(APPEND ATEX_LIB_SOURCES)
function(atex_deform_tests)
endfunction()
