# Compiler flags shared by every Hardcopy target: hardcopy_add_library / hardcopy_add_executable apply them.
add_library(hardcopy_flags INTERFACE)
target_compile_options(hardcopy_flags INTERFACE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                                -Wold-style-cast -Wcast-align -Woverloaded-virtual)
if(HARDCOPY_WERROR)
  target_compile_options(hardcopy_flags INTERFACE -Werror)
endif()

# Unity builds: each target's sources compiled in batches of 8 (the tests: one file per room, in
# tests/CMakeLists.txt), so the headers most files share (Eigen, nlohmann::json, GoogleTest, the
# project's own) are parsed once per batch instead of once per file. Measured on the 2-core CI
# machine kind with g++ 12, clean and without ccache: the unit tests' objects 8 min 41 s -> 4 min
# 20 s, the 31 libraries other than CGAL's 746 s -> 409 s. The price: names at a
# source file's namespace scope (anonymous namespaces included) must be unique within its target,
# and an overload of the same name from another file could be chosen silently, so give helpers
# distinct names or share them from a header. g++'s -Wsubobject-linkage, which flags types from an
# anonymous namespace used in a header's classes, mistakes the batched sources for headers.
option(HARDCOPY_UNITY_BUILD "Compile each target's sources in batches (faster clean builds)" ON)
set(CMAKE_UNITY_BUILD ${HARDCOPY_UNITY_BUILD})
if(HARDCOPY_UNITY_BUILD AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  target_compile_options(hardcopy_flags INTERFACE -Wno-subobject-linkage)
endif()

if(HARDCOPY_SANITIZE)
  # AddressSanitizer and UndefinedBehaviorSanitizer's checks that cost little to compile. Left out:
  # null and alignment (ASan reports a null access as a SEGV with its stack; x86 tolerates
  # misalignment), pointer-overflow and object-size (ASan's bounds checks cover the accesses).
  # The RTTI-free firmware libraries leave out vptr (firmware_host/).
  # Measured with clang 14 -O1 on processing/fem/src/corotational.cpp: 42 s with all of
  # -fsanitize=undefined, 24-27 s with this set, 20 s without sanitizers (the sanitizer build is
  # the longest stage of CI).
  set(_ubsan signed-integer-overflow,shift,integer-divide-by-zero,unreachable,return,bool,enum,float-cast-overflow,bounds,vla-bound,nonnull-attribute,returns-nonnull-attribute,vptr)
  set(_san -fsanitize=address,${_ubsan} -fno-sanitize-recover=undefined -fno-omit-frame-pointer)
  add_compile_options(${_san})
  add_link_options(-fsanitize=address,undefined)
endif()
if(HARDCOPY_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "HARDCOPY_FUZZ needs clang (configure with CXX=clang++)")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()

# hardcopy_add_library(NAME SOURCES ... PUBLIC ... PRIVATE ...): a library with public headers in
# ./include, registered in the global HARDCOPY_LIBRARIES list (the `hardcopy` tool links them all). Sources are globbed so that adding a file needs no CMake edit.
function(hardcopy_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC;PRIVATE" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(${name} PUBLIC ${ARG_PUBLIC} PRIVATE hardcopy_flags ${ARG_PRIVATE})
  set_property(GLOBAL APPEND PROPERTY HARDCOPY_LIBRARIES ${name})
endfunction()

# hardcopy_add_subdirectories(): adds every direct sub-folder of the current folder that has a
# CMakeLists.txt, so a room's parts (e.g. processing/fem, processing/material) need no edit here.
function(hardcopy_add_subdirectories)
  file(GLOB _children LIST_DIRECTORIES true CONFIGURE_DEPENDS ${CMAKE_CURRENT_SOURCE_DIR}/*)
  list(SORT _children)
  foreach(_child ${_children})
    if(IS_DIRECTORY ${_child} AND EXISTS ${_child}/CMakeLists.txt)
      add_subdirectory(${_child})
    endif()
  endforeach()
endfunction()
