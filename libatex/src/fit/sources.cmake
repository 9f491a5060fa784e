# Module 'fit': sources appended to libatex; tests registered in atex_fit_tests().
list(APPEND ATEX_LIB_SOURCES)
function(atex_fit_tests)
endfunction()
