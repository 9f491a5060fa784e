# Module 'data': images, zip/.npy/.npz, datasets, point clouds (PLY, COLMAP), multi-view
# stereo, initialisation.
list(APPEND ATEX_LIB_SOURCES
  ${CMAKE_CURRENT_LIST_DIR}/zip_reader.cc
  ${CMAKE_CURRENT_LIST_DIR}/zip_writer.cc
  ${CMAKE_CURRENT_LIST_DIR}/npy.cc
  ${CMAKE_CURRENT_LIST_DIR}/image_io.cc
  ${CMAKE_CURRENT_LIST_DIR}/image_png.cc
  ${CMAKE_CURRENT_LIST_DIR}/image_jpeg.cc
  ${CMAKE_CURRENT_LIST_DIR}/image_exr.cc
  ${CMAKE_CURRENT_LIST_DIR}/image_ops.cc
  ${CMAKE_CURRENT_LIST_DIR}/image_cache.cc
  ${CMAKE_CURRENT_LIST_DIR}/dataset.cc
  ${CMAKE_CURRENT_LIST_DIR}/dataset_panoptic.cc
  ${CMAKE_CURRENT_LIST_DIR}/dataset_dnerf.cc
  ${CMAKE_CURRENT_LIST_DIR}/dataset_n3dv.cc
  ${CMAKE_CURRENT_LIST_DIR}/video_frames.cc
  ${CMAKE_CURRENT_LIST_DIR}/dataset_nerfstudio.cc
  ${CMAKE_CURRENT_LIST_DIR}/dataset_colmap.cc
  ${CMAKE_CURRENT_LIST_DIR}/transforms_json.cc
  ${CMAKE_CURRENT_LIST_DIR}/colmap_model.cc
  ${CMAKE_CURRENT_LIST_DIR}/knn.cc
  ${CMAKE_CURRENT_LIST_DIR}/init.cc
  ${CMAKE_CURRENT_LIST_DIR}/init_sources.cc
  ${CMAKE_CURRENT_LIST_DIR}/transient_hull.cc
  ${CMAKE_CURRENT_LIST_DIR}/mvs.cc
  ${CMAKE_CURRENT_LIST_DIR}/mvs_fusion.cc
  ${CMAKE_CURRENT_LIST_DIR}/point_cloud_ply.cc
  ${CMAKE_CURRENT_LIST_DIR}/point_cloud_colmap.cc)
function(atex_data_tests)
  set(dir ${CMAKE_CURRENT_FUNCTION_LIST_DIR})
  atex_add_test(NAME data_io_test
    SOURCES ${dir}/zip_test.cc ${dir}/npy_test.cc ${dir}/image_test.cc ${dir}/point_cloud_test.cc
    LIBS atex PNG::PNG ZLIB::ZLIB
    LABELS hostile
    TIMEOUT 300)
  atex_add_test(NAME data_dataset_test
    SOURCES ${dir}/dataset_test.cc ${dir}/init_test.cc ${dir}/dataset_nerfstudio_test.cc ${dir}/dataset_colmap_test.cc
            ${dir}/dataset_video_test.cc ${dir}/dataset_dnerf_test.cc ${dir}/dataset_n3dv_test.cc
    LIBS atex
    TIMEOUT 600)
  # The ffmpeg command encodes the N3DV video test's .mp4 files (Debian package ffmpeg).
  find_program(ATEX_FFMPEG_EXECUTABLE ffmpeg)
  if(TARGET data_dataset_test)
    set(ffmpeg "${ATEX_FFMPEG_EXECUTABLE}")
    if(NOT ATEX_FFMPEG_EXECUTABLE)
      set(ffmpeg "")
    endif()
    target_compile_definitions(data_dataset_test PRIVATE ATEX_FFMPEG_EXECUTABLE="${ffmpeg}")
  endif()
  atex_add_test(NAME data_transient_hull_test
    SOURCES ${dir}/transient_hull_test.cc
    LIBS atex
    TIMEOUT 300)
  atex_add_test(NAME data_mvs_test
    SOURCES ${dir}/mvs_test.cc
    LIBS atex
    TIMEOUT 600)
endfunction()
