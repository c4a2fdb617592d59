# Third-party libraries, all from Debian (scripts/setup installs them).
find_package(Threads REQUIRED)
find_package(Eigen3 3.4 REQUIRED NO_MODULE)
find_package(fmt REQUIRED)
find_package(spdlog REQUIRED)
find_package(yaml-cpp REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(CLI11 REQUIRED)
find_package(ZLIB REQUIRED)
find_package(TBB REQUIRED)
# CGAL is header-only here; only the targets that need it link it (see common/geometry/CMakeLists.txt).
set(CGAL_DO_NOT_WARN_ABOUT_CMAKE_BUILD_TYPE TRUE)
find_package(CGAL REQUIRED)
find_package(GTest REQUIRED)
# fabrication/articulation: skinned characters (glTF, FBX, COLLADA, .x); Debian's libassimp-dev.
find_package(assimp 5.2 REQUIRED)
if(HARDCOPY_BENCH)
  find_package(benchmark REQUIRED)
endif()
find_package(PkgConfig REQUIRED)
# Debian's libzip CMake config names tools that live in other packages; pkg-config is reliable.
pkg_check_modules(LIBZIP REQUIRED IMPORTED_TARGET libzip)
pkg_check_modules(LIB3MF IMPORTED_TARGET lib3MF)

# processing: TetGen (no CMake config in Debian; built with -DTETLIBRARY), SuiteSparse/CHOLMOD, Ceres.
find_path(TETGEN_INCLUDE_DIR tetgen.h REQUIRED)
find_library(TETGEN_LIBRARY tet REQUIRED)
add_library(TetGen::TetGen UNKNOWN IMPORTED)
set_target_properties(TetGen::TetGen PROPERTIES IMPORTED_LOCATION ${TETGEN_LIBRARY}
  INTERFACE_INCLUDE_DIRECTORIES ${TETGEN_INCLUDE_DIR} INTERFACE_COMPILE_DEFINITIONS TETLIBRARY)
# BLAS for CHOLMOD's supernodal kernels: OpenBLAS, linked directly into everything that uses
# CHOLMOD. Debian's libceres links ATLAS's libf77blas, whose dgemm_ would otherwise win the symbol
# lookup (it comes first among the libraries' dependencies) and is ~2x slower here (bench_fem_step:
# 10k tets 49 ms vs 27 ms per factorisation). A direct dependency is searched before any indirect one.
find_library(OPENBLAS_LIBRARY openblas REQUIRED)
# libgomp: the OpenMP runtime CHOLMOD uses; common/openmp.h calls it to run CHOLMOD serially.
find_library(GOMP_LIBRARY NAMES gomp libgomp.so.1 REQUIRED)
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
find_library(SUITESPARSE_CONFIG_LIBRARY suitesparseconfig REQUIRED)
add_library(SuiteSparse::CHOLMOD UNKNOWN IMPORTED)
set_target_properties(SuiteSparse::CHOLMOD PROPERTIES IMPORTED_LOCATION ${CHOLMOD_LIBRARY}
  INTERFACE_INCLUDE_DIRECTORIES ${CHOLMOD_INCLUDE_DIR}
  INTERFACE_LINK_LIBRARIES "${SUITESPARSE_CONFIG_LIBRARY};${OPENBLAS_LIBRARY}")
find_package(Ceres REQUIRED)

# calibration and tracking: OpenCV 4.6 (Debian); aruco is in libopencv-contrib-dev.
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs calib3d features2d aruco)
# What the libraries link: every module but the image codecs, which bring ~110 shared libraries
# (GDAL, GDCM, video codecs; 0.14 s to load in every process) and which calibration/cameras
# loads on first use (image_codecs.cpp). Tests that write images link ${OpenCV_LIBS}.
set(HARDCOPY_OPENCV_LIBS ${OpenCV_LIBS})
list(REMOVE_ITEM HARDCOPY_OPENCV_LIBS opencv_imgcodecs)

# rig: compression for MCAP chunks, device access, image files.
pkg_check_modules(ZSTD REQUIRED IMPORTED_TARGET libzstd)
pkg_check_modules(LZ4 REQUIRED IMPORTED_TARGET liblz4)
pkg_check_modules(LIBUSB REQUIRED IMPORTED_TARGET libusb-1.0)
pkg_check_modules(LIBMODBUS REQUIRED IMPORTED_TARGET libmodbus)
pkg_check_modules(ARAVIS REQUIRED IMPORTED_TARGET aravis-0.8)
pkg_check_modules(LIBGPIOD REQUIRED IMPORTED_TARGET libgpiod)
pkg_check_modules(LIBCAMERA REQUIRED IMPORTED_TARGET libcamera)
find_package(PNG REQUIRED)

# the lab's view: plots (Cairo: PNG and SVG surfaces), rigd's live page (cpp-httplib; Debian ships it
# as a library whose pkg-config flags must match its build).
pkg_check_modules(CAIRO REQUIRED IMPORTED_TARGET cairo)
pkg_check_modules(HTTPLIB REQUIRED IMPORTED_TARGET cpp-httplib)
# fabrication/abstraction: SVG input (expat).
find_package(EXPAT REQUIRED)
