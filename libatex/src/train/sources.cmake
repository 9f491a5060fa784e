# Module 'train': sources appended to libatex; tests registered in atex_train_tests().
list(APPEND ATEX_LIB_SOURCES)
function(atex_train_tests)
endfunction()
