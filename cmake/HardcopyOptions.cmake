# Compiler flags shared by every Hardcopy target: hardcopy_add_library / hardcopy_add_executable apply them.
add_library(hardcopy_flags INTERFACE)
target_compile_options(hardcopy_flags INTERFACE -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
                                                -Wold-style-cast -Wcast-align -Woverloaded-virtual)
if(HARDCOPY_WERROR)
  target_compile_options(hardcopy_flags INTERFACE -Werror)
endif()

if(HARDCOPY_SANITIZE)
  set(_san -fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer)
  add_compile_options(${_san})
  add_link_options(-fsanitize=address,undefined)
endif()
if(HARDCOPY_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "HARDCOPY_FUZZ needs clang (configure with CXX=clang++)")
  endif()
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()

# hardcopy_add_library(NAME DIR [DEPS ...]): a room's library from DIR/src/*.cpp with public headers in
# DIR/include. Sources are globbed so that adding a file needs no CMake edit.
function(hardcopy_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC;PRIVATE" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(${name} PUBLIC ${ARG_PUBLIC} PRIVATE hardcopy_flags ${ARG_PRIVATE})
endfunction()
