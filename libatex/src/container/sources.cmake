# Module 'container': sources appended to libatex; tests registered in atex_container_tests().
list(APPEND ATEX_LIB_SOURCES)
function(atex_container_tests)
endfunction()
