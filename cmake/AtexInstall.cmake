# `cmake --install BUILD [--prefix DIR]`: the headers, the static libraries, the `atex`
# command, the CMake package (find_package(atex) -> atex::atex, atex::converters and,
# where built, atex::cuda) and a pkg-config file (atex.pc).
#
# The libraries are static, so their private dependencies (zstd, zlib, libpng, libjpeg and
# the optional formats) must be found again by a consumer: atexConfig.cmake does that with
# find_dependency for exactly the packages this build used, and atex.pc lists them.
include(CMakePackageConfigHelpers)

set(ATEX_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/atex CACHE STRING "Where atexConfig.cmake is installed")

install(DIRECTORY ${PROJECT_SOURCE_DIR}/libatex/include/ ${PROJECT_SOURCE_DIR}/converters/include/
                  ${ATEX_GENERATED_INCLUDE_DIR}/
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT atex_development FILES_MATCHING PATTERN "*.h")
set(atex_install_targets atex atex_converters)
if(TARGET atex_cuda)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/kernels/include/
          DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT atex_development FILES_MATCHING PATTERN "*.h")
  list(APPEND atex_install_targets atex_cuda)
endif()
install(TARGETS ${atex_install_targets} EXPORT atexTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT atex_development
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS atex_cli RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT atex_runtime)
install(EXPORT atexTargets NAMESPACE atex:: DESTINATION ${ATEX_INSTALL_CMAKEDIR} COMPONENT atex_development)

# What atexConfig.cmake must find again (the same packages, found the same way).
set(ATEX_CONFIG_HAVE_OPENEXR ${OpenEXR_FOUND})
set(ATEX_CONFIG_HAVE_DRACO ${draco_FOUND})
set(ATEX_CONFIG_HAVE_TINYGLTF ${TinyGLTF_FOUND})
set(ATEX_CONFIG_HAVE_MESHOPT ${meshoptimizer_FOUND})
set(ATEX_CONFIG_HAVE_OPENMP ${OpenMP_CXX_FOUND})
if(WEBP_FOUND)  # pkg_check_modules: "1" or unset
  set(ATEX_CONFIG_HAVE_WEBP ON)
else()
  set(ATEX_CONFIG_HAVE_WEBP OFF)
endif()
if(FFMPEG_FOUND)  # pkg_check_modules: "1" or unset
  set(ATEX_CONFIG_HAVE_FFMPEG ON)
else()
  set(ATEX_CONFIG_HAVE_FFMPEG OFF)
endif()
if(TARGET atex_cuda)
  set(ATEX_CONFIG_HAVE_CUDA ON)
else()
  set(ATEX_CONFIG_HAVE_CUDA OFF)
endif()
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/atexConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/cmake/atexConfig.cmake
                              INSTALL_DESTINATION ${ATEX_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/cmake/atexConfigVersion.cmake
                                 VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/cmake/atexConfig.cmake ${PROJECT_BINARY_DIR}/cmake/atexConfigVersion.cmake
        DESTINATION ${ATEX_INSTALL_CMAKEDIR} COMPONENT atex_development)

# pkg-config: static libraries, so `pkg-config --static --libs atex` gives the full link line.
set(ATEX_PC_REQUIRES_PRIVATE "libzstd zlib libpng libjpeg")
set(ATEX_PC_LIBS_PRIVATE "-lpthread")
if(ATEX_CONFIG_HAVE_WEBP)
  string(APPEND ATEX_PC_REQUIRES_PRIVATE " libwebp")
endif()
if(ATEX_CONFIG_HAVE_FFMPEG)
  # As plain -l flags, not Requires.private: `pkg-config --static` would pull in FFmpeg's own
  # private dependencies (libgme, libopenmpt, libbluray, ...), whose static libraries Debian does
  # not ship; libatex needs only these four, linked shared.
  string(APPEND ATEX_PC_LIBS_PRIVATE " -lavformat -lavcodec -lswscale -lavutil")
endif()
if(OpenEXR_FOUND)
  string(APPEND ATEX_PC_REQUIRES_PRIVATE " OpenEXR")
endif()
if(draco_FOUND)
  string(APPEND ATEX_PC_LIBS_PRIVATE " -ldraco")
endif()
if(meshoptimizer_FOUND)
  string(APPEND ATEX_PC_LIBS_PRIVATE " -lmeshoptimizer")
endif()
if(OpenMP_CXX_FOUND)
  string(APPEND ATEX_PC_LIBS_PRIVATE " ${OpenMP_CXX_FLAGS}")
  set(ATEX_PC_CFLAGS_EXTRA "${OpenMP_CXX_FLAGS}")
endif()
if(TARGET atex_cuda)
  set(ATEX_PC_LIBS_CUDA "-latex_cuda")
  string(APPEND ATEX_PC_LIBS_PRIVATE " -L${CUDAToolkit_LIBRARY_DIR} -lcublasLt -lcublas -lcudart")
endif()
file(RELATIVE_PATH ATEX_PC_PREFIX_FROM_PCDIR /prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig /prefix)
string(REGEX REPLACE "/$" "" ATEX_PC_PREFIX_FROM_PCDIR "${ATEX_PC_PREFIX_FROM_PCDIR}")
configure_file(${PROJECT_SOURCE_DIR}/cmake/atex.pc.in ${PROJECT_BINARY_DIR}/cmake/atex.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/cmake/atex.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig
        COMPONENT atex_development)
