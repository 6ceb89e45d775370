# One function applies the project's warning, architecture and sanitizer flags to every target.
function(evpipe_set_flags target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow)
  if(EVPIPE_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# Architecture: portable by default (the service runs on industrial PCs that are not the build machine).
if(CMAKE_SYSTEM_PROCESSOR MATCHES "x86_64|AMD64")
  if(EVPIPE_NATIVE)
    add_compile_options(-march=native)
  else()
    add_compile_options(-march=x86-64-v2)
  endif()
endif()

# float-cast-overflow (a double outside int's range cast to int: UB) is part of clang's "undefined" group but not
# of GCC's, so it is named.
if(EVPIPE_SANITIZE)
  add_compile_options(-fsanitize=address,undefined,float-cast-overflow -fno-omit-frame-pointer
                      -fno-sanitize-recover=undefined,float-cast-overflow)
  add_link_options(-fsanitize=address,undefined,float-cast-overflow)
endif()
if(EVPIPE_FUZZ)
  if(NOT CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    message(FATAL_ERROR "EVPIPE_FUZZ=ON needs clang (libFuzzer): configure with -DCMAKE_C_COMPILER=clang "
                        "-DCMAKE_CXX_COMPILER=clang++ (tools/run_fuzzers.sh does)")
  endif()
  # libFuzzer (clang only): every library gets coverage instrumentation without libFuzzer's main
  # (-fsanitize=fuzzer-no-link) plus ASan/UBSan, so a bug deep inside a reader is a finding; the fuzz
  # targets themselves link with -fsanitize=fuzzer (tests/fuzz/CMakeLists.txt). UB aborts (no recovery).
  add_compile_options(-fsanitize=fuzzer-no-link,address,undefined -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=address,undefined)
endif()
if(EVPIPE_TSAN)
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  add_link_options(-fsanitize=thread)
endif()

# Declares an evpipe library: libs/<name>/{include,src}, target evpipe_<name>, alias evpipe::<name>.
function(evpipe_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(evpipe_${name} ${ARG_SOURCES})
  add_library(evpipe::${name} ALIAS evpipe_${name})
  target_include_directories(evpipe_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(evpipe_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  evpipe_set_flags(evpipe_${name})
endfunction()

# The numerical libraries build at -O2 in the sanitizer builds (Debug): at -O0 their Eigen expressions and
# per-event loops run tens of times slower under ASan and the tests that render scenes and solve poses took
# minutes each; at -O1 GCC still leaves Eigen's small packet functions out of line (the slow-target pose test:
# 158 s at -O1, 78 s at -O2). ASan checks everything at -O2 too (UBSan: below). GCC 12 reports false
# maybe-uninitialized warnings in Eigen / std headers under the sanitizers, hence the -Wno.
# UBSan's alignment and null checks are left out of these libraries: they guard every reference Eigen's expression
# templates bind and tripled the compile time of the pose sources under ASan (initialiser.cpp: ASan alone 37 s,
# with all of UBSan 113 s, without those two 44 s). A null dereference still stops under ASan, Eigen's own asserts
# (on in these Debug builds) catch a misaligned fixed-size object, and the readers and the runtime keep both
# (the test code goes without them too: tests/CMakeLists.txt).
function(evpipe_optimise_under_sanitizers target)
  if(EVPIPE_SANITIZE OR EVPIPE_TSAN)
    target_compile_options(${target} PRIVATE -O2 $<$<CXX_COMPILER_ID:GNU>:-Wno-maybe-uninitialized>)
  endif()
  if(EVPIPE_SANITIZE)
    target_compile_options(${target} PRIVATE -fno-sanitize=alignment,null)
  endif()
endfunction()
