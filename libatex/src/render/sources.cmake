# Module 'render': sources appended to libatex; tests registered in atex_render_tests().
list(APPEND ATEX_LIB_SOURCES)
function(atex_render_tests)
endfunction()
