# Module 'data': sources appended to libatex; tests registered in atex_data_tests().
list(APPEND ATEX_LIB_SOURCES)
function(atex_data_tests)
endfunction()
