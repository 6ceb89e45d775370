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

# Declares an evpipe library: libs/<name>/{include,src}, target evpipe_<name>, alias evpipe::<name>. NUMERICAL: the
# library builds optimised under the sanitizers (evpipe_optimise_under_sanitizers, below).
function(evpipe_add_library name)
  cmake_parse_arguments(ARG "NUMERICAL" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(evpipe_${name} ${ARG_SOURCES})
  add_library(evpipe::${name} ALIAS evpipe_${name})
  target_include_directories(evpipe_${name} PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include)
  target_link_libraries(evpipe_${name} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  evpipe_set_flags(evpipe_${name})
  if(ARG_NUMERICAL)
    evpipe_optimise_under_sanitizers(evpipe_${name})
    evpipe_use_pch(evpipe_${name} NUMERICAL)
  else()
    evpipe_use_pch(evpipe_${name})
  endif()
endfunction()

# Precompiled headers of the libraries and programs (CMake's REUSE_FROM; the tests have their own, see
# tests/CMakeLists.txt): Eigen, fmt and the common standard headers took ~1 s to parse in each of the ~110 sources,
# once per build preset. GCC uses a precompiled header only in a source built with the same flags and the same
# macros where the headers read them: every user gets -pthread as the header does (it defines _REENTRANT, which the
# standard headers read), and under the sanitizers the numerical libraries, built with other flags, have a header
# of their own. CMake adds -Winvalid-pch: under -Werror a source GCC refuses the header in fails to build (a new
# per-target flag or macro the headers read, e.g. -fopenmp, needs its own header). The fuzz build (clang) goes
# without, and so catches a missing include the header would hide.
set(EVPIPE_PCH_HEADERS <Eigen/Core> <Eigen/Geometry> <fmt/format.h> <algorithm> <array> <chrono> <cmath> <cstdint>
                       <functional> <limits> <memory> <optional> <span> <stdexcept> <string> <string_view> <utility>
                       <vector>)

# Declares the targets that build the headers (evpipe_pch, and evpipe_numerical_pch under the sanitizers); called
# once Eigen and fmt are found.
function(evpipe_declare_pch)
  if(EVPIPE_FUZZ)
    return()
  endif()
  set(names evpipe_pch)
  if(EVPIPE_SANITIZE OR EVPIPE_TSAN)
    list(APPEND names evpipe_numerical_pch)
  endif()
  foreach(name IN LISTS names)
    add_library(${name} OBJECT ${PROJECT_SOURCE_DIR}/cmake/pch.cpp)
    target_link_libraries(${name} PRIVATE Eigen3::Eigen fmt::fmt)
    target_compile_options(${name} PRIVATE -pthread)
    evpipe_set_flags(${name})
    target_precompile_headers(${name} PRIVATE ${EVPIPE_PCH_HEADERS})
  endforeach()
  if(TARGET evpipe_numerical_pch)
    evpipe_optimise_under_sanitizers(evpipe_numerical_pch)
  endif()
endfunction()

# evpipe_use_pch(<target> [NUMERICAL]): <target>'s sources use the precompiled header of its flags.
function(evpipe_use_pch target)
  if(EVPIPE_FUZZ)
    return()
  endif()
  cmake_parse_arguments(ARG "NUMERICAL" "" "" ${ARGN})
  set(pch evpipe_pch)
  if(ARG_NUMERICAL AND TARGET evpipe_numerical_pch)
    set(pch evpipe_numerical_pch)
  endif()
  target_link_libraries(${target} PRIVATE Eigen3::Eigen fmt::fmt)
  target_compile_options(${target} PRIVATE -pthread)
  target_precompile_headers(${target} REUSE_FROM ${pch})
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
