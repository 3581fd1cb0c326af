# The install test: `cmake --install` into a fresh prefix, then a tiny
# external project (tests/capi/external) found with find_package(earshot
# CONFIG) and built against it (shared, static, C++), and the same C program
# built with pkg-config; every program must run and print "ok".
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... -DGENERATOR=... -DLIBDIR=... -DC_COMPILER=... -P install_test.cmake
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "ran: ${ARGN}\n${out}")
endfunction()

set(prefix "${WORK_DIR}/prefix")
file(REMOVE_RECURSE "${WORK_DIR}")
file(MAKE_DIRECTORY "${WORK_DIR}")
run("${CMAKE_COMMAND}" --install "${BUILD_DIR}" --prefix "${prefix}")
foreach(f include/earshot/earshot.h include/earshot/earshot.hpp include/earshot/earshot_version.h ${LIBDIR}/libearshot.a ${LIBDIR}/pkgconfig/earshot.pc
          ${LIBDIR}/cmake/earshot/earshotConfig.cmake share/earshot/hrtf/FHK_HRIR_L2354.sofa
          libexec/earshot/earshot-sofa-probe)
  if(NOT EXISTS "${prefix}/${f}")
    message(FATAL_ERROR "not installed: ${f}")
  endif()
endforeach()

# The default HRTF set comes prepared (share/earshot/prepared): the installed
# tool, run with an empty cache folder, finds both rates already prepared.
file(GLOB _prepared "${prefix}/share/earshot/prepared/hrtf-*.bin")
list(LENGTH _prepared _count)
if(NOT _count EQUAL 2)
  message(FATAL_ERROR "installed prepared HRTF sets: ${_count}, expected 2")
endif()
set(ENV{EARSHOT_CACHE_DIR} "${WORK_DIR}/empty_cache")
unset(ENV{EARSHOT_HRTF_DIR})
execute_process(COMMAND "${prefix}/bin/earshot" cache --prepare RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(REGEX MATCHALL "already prepared" _hits "${out}")
list(LENGTH _hits _hitCount)
if(NOT rc EQUAL 0 OR NOT _hitCount EQUAL 2)
  message(FATAL_ERROR "the installed earshot did not read the prepared set (${rc}):\n${out}\n${err}")
endif()
unset(ENV{EARSHOT_CACHE_DIR})

# CMake package.
# Only the public headers are installed.
file(GLOB_RECURSE _headers RELATIVE "${prefix}/include" "${prefix}/include/*")
list(SORT _headers)
if(NOT _headers STREQUAL "earshot/earshot.h;earshot/earshot.hpp;earshot/earshot_version.h")
  message(FATAL_ERROR "installed headers beyond the public API: ${_headers}")
endif()

# A C-only CMake project, shared and static.
run("${CMAKE_COMMAND}" -S "${SOURCE_DIR}/tests/capi/external_c" -B "${WORK_DIR}/build_c" -G "${GENERATOR}"
    -DCMAKE_BUILD_TYPE=Release "-DCMAKE_PREFIX_PATH=${prefix}")
run("${CMAKE_COMMAND}" --build "${WORK_DIR}/build_c")
run("${WORK_DIR}/build_c/c_only_shared" "${prefix}")
run("${WORK_DIR}/build_c/c_only_static" -)

run("${CMAKE_COMMAND}" -S "${SOURCE_DIR}/tests/capi/external" -B "${WORK_DIR}/build" -G "${GENERATOR}"
    -DCMAKE_BUILD_TYPE=Release "-DCMAKE_PREFIX_PATH=${prefix}")
run("${CMAKE_COMMAND}" --build "${WORK_DIR}/build")
run("${WORK_DIR}/build/consumer_c" "${prefix}")
run("${WORK_DIR}/build/consumer_cpp")
run("${WORK_DIR}/build/consumer_static" -)

# pkg-config.
set(ENV{PKG_CONFIG_PATH} "${prefix}/${LIBDIR}/pkgconfig")
execute_process(COMMAND pkg-config --cflags --libs earshot RESULT_VARIABLE rc OUTPUT_VARIABLE flags
                OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "pkg-config does not know earshot")
endif()
separate_arguments(flags UNIX_COMMAND "${flags}")
run("${C_COMPILER}" -std=c99 -Wall -Wextra -pedantic -Werror "${SOURCE_DIR}/tests/capi/external/consumer.c" ${flags}
    -o "${WORK_DIR}/consumer_pkgconfig")
set(ENV{LD_LIBRARY_PATH} "${prefix}/${LIBDIR}")
run("${WORK_DIR}/consumer_pkgconfig" "${prefix}")
# And `earshot --version` says the project's version.
run("${prefix}/bin/earshot" --version)
execute_process(COMMAND "${prefix}/bin/earshot" --version OUTPUT_VARIABLE _v OUTPUT_STRIP_TRAILING_WHITESPACE)
if(NOT _v STREQUAL "earshot ${VERSION}")
  message(FATAL_ERROR "earshot --version says '${_v}', the project is ${VERSION}")
endif()
file(REMOVE_RECURSE "${WORK_DIR}")
