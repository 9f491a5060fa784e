# Module 'metrics': sources appended to libatex; tests registered in atex_metrics_tests().
list(APPEND ATEX_LIB_SOURCES)
function(atex_metrics_tests)
endfunction()
