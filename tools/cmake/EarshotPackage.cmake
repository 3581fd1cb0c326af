# libearshot and its installation (included by the top-level CMakeLists.txt
# after every module and tools/).
#
#   earshot_shared  libearshot.so  (exported as earshot::earshot)
#   earshot_static  libearshot.a   (exported as earshot::earshot_static)
#
# Both are made of the object files of every module (earshot_module()
# records them in EARSHOT_MODULE_TARGETS; the modules are compiled
# position-independent), so each holds the whole engine: the C API, the C++
# headers' symbols and everything beneath. The `earshot` executable keeps its
# name, hence the target names.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

get_property(_earshot_modules GLOBAL PROPERTY EARSHOT_MODULE_TARGETS)
set(_earshot_objects "")
foreach(_m IN LISTS _earshot_modules)
  list(APPEND _earshot_objects $<TARGET_OBJECTS:${_m}>)
endforeach()

# What the modules link beyond themselves (the header-only nlohmann_json,
# CLI11 are needed at compile time only). The package config finds
# these for the static library; keep the three lists in step.
set(EARSHOT_EXTERNAL_LIBS embree kissfft::kissfft SndFile::sndfile MySofa::mysofa TinyGLTF::TinyGLTF Qhull::qhull_r PkgConfig::SOXR Threads::Threads)
set(EARSHOT_PC_LIBS_PRIVATE "-lembree3 -lkissfft-float -lsndfile -lmysofa -ltinygltf -lqhull_r -lsoxr -lpthread -lstdc++ -lm")

set(_earshot_includes $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include> $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
  $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)

add_library(earshot_shared SHARED ${_earshot_objects})
add_dependencies(earshot_shared ${_earshot_modules})
target_include_directories(earshot_shared PUBLIC ${_earshot_includes})
target_link_libraries(earshot_shared PRIVATE ${EARSHOT_EXTERNAL_LIBS})
set_target_properties(earshot_shared PROPERTIES
  OUTPUT_NAME earshot EXPORT_NAME earshot LINKER_LANGUAGE CXX
  VERSION ${PROJECT_VERSION} SOVERSION ${PROJECT_VERSION_MAJOR}.${PROJECT_VERSION_MINOR}
  LIBRARY_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/lib)
# Fail the link on an undefined symbol rather than in a user's program.
target_link_options(earshot_shared PRIVATE -Wl,--no-undefined
  -Wl,--version-script=${CMAKE_CURRENT_LIST_DIR}/earshot.map)
set_property(TARGET earshot_shared APPEND PROPERTY LINK_DEPENDS ${CMAKE_CURRENT_LIST_DIR}/earshot.map)
add_library(earshot::earshot ALIAS earshot_shared)

add_library(earshot_static STATIC ${_earshot_objects})
add_dependencies(earshot_static ${_earshot_modules})
target_include_directories(earshot_static PUBLIC ${_earshot_includes})
# The C++ runtime and libm too: a C-only project links with the C driver,
# which adds neither.
target_link_libraries(earshot_static INTERFACE ${EARSHOT_EXTERNAL_LIBS} stdc++ m)
set_target_properties(earshot_static PROPERTIES
  OUTPUT_NAME earshot EXPORT_NAME earshot_static LINKER_LANGUAGE CXX
  ARCHIVE_OUTPUT_DIRECTORY ${PROJECT_BINARY_DIR}/lib)
add_library(earshot::earshot_static ALIAS earshot_static)

# samples/game_loop.c: plain C99 against the shared library, built with the
# project so it never rots (run by tests/capi).
add_executable(earshot_game_loop ${PROJECT_SOURCE_DIR}/samples/game_loop.c)
target_link_libraries(earshot_game_loop PRIVATE earshot_shared m)
set_target_properties(earshot_game_loop PROPERTIES C_STANDARD 99 C_STANDARD_REQUIRED ON C_EXTENSIONS OFF)
target_compile_options(earshot_game_loop PRIVATE -Wall -Wextra -pedantic -Werror)

# ---- install ----
set(EARSHOT_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/earshot)

# The public headers only: the C API, its C++ layer and the version. The
# engine's internal headers (include/earshot/<module>/) are not an API.
install(FILES ${PROJECT_SOURCE_DIR}/include/earshot/earshot.h ${PROJECT_SOURCE_DIR}/include/earshot/earshot.hpp
  ${PROJECT_BINARY_DIR}/include/earshot/earshot_version.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/earshot)
install(TARGETS earshot_shared EXPORT earshotTargets
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS earshot_static EXPORT earshotStaticTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(TARGETS earshot RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# HrtfSet::load finds it relative to the installed library (libexec/earshot).
install(TARGETS earshot-sofa-probe RUNTIME DESTINATION ${CMAKE_INSTALL_LIBEXECDIR}/earshot)
install(EXPORT earshotTargets NAMESPACE earshot:: DESTINATION ${EARSHOT_CMAKE_DIR})
install(EXPORT earshotStaticTargets NAMESPACE earshot:: DESTINATION ${EARSHOT_CMAKE_DIR})
# The default HRTF and materials; defaultHrtfPath() finds share/earshot/hrtf
# relative to the installed library.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/hrtf/ DESTINATION ${CMAKE_INSTALL_DATADIR}/earshot/hrtf)
# The default set's prepared form (tools/CMakeLists.txt, earshot_prepared_hrtf).
install(DIRECTORY ${EARSHOT_PREPARED_DIR}/ DESTINATION ${CMAKE_INSTALL_DATADIR}/earshot/prepared
        FILES_MATCHING PATTERN "hrtf-*.bin")
install(FILES ${PROJECT_SOURCE_DIR}/materials/default.json DESTINATION ${CMAKE_INSTALL_DATADIR}/earshot/materials)

configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/earshotConfig.cmake.in
  ${PROJECT_BINARY_DIR}/earshotConfig.cmake INSTALL_DESTINATION ${EARSHOT_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/earshotConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/earshotConfig.cmake ${PROJECT_BINARY_DIR}/earshotConfigVersion.cmake
  ${CMAKE_CURRENT_LIST_DIR}/FindMySofa.cmake ${CMAKE_CURRENT_LIST_DIR}/FindSndFile.cmake
  DESTINATION ${EARSHOT_CMAKE_DIR})

# pkg-config: relocatable (the prefix is found from the .pc file's place).
file(RELATIVE_PATH EARSHOT_PC_TO_PREFIX "/prefix/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/prefix")
string(REGEX REPLACE "/$" "" EARSHOT_PC_TO_PREFIX "${EARSHOT_PC_TO_PREFIX}")
configure_file(${CMAKE_CURRENT_LIST_DIR}/earshot.pc.in ${PROJECT_BINARY_DIR}/earshot.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/earshot.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
