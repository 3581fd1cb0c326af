# Finds libmysofa (Debian: libmysofa-dev), which ships only a pkg-config file.
# Defines the imported target MySofa::mysofa (the shared library).
find_package(PkgConfig QUIET)
if(PkgConfig_FOUND)
  pkg_check_modules(PC_MYSOFA QUIET libmysofa)
endif()
find_path(MySofa_INCLUDE_DIR mysofa.h HINTS ${PC_MYSOFA_INCLUDE_DIRS})
find_library(MySofa_LIBRARY NAMES libmysofa.so mysofa HINTS ${PC_MYSOFA_LIBRARY_DIRS})
include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(MySofa REQUIRED_VARS MySofa_LIBRARY MySofa_INCLUDE_DIR)
if(MySofa_FOUND AND NOT TARGET MySofa::mysofa)
  add_library(MySofa::mysofa UNKNOWN IMPORTED)
  set_target_properties(MySofa::mysofa PROPERTIES
    IMPORTED_LOCATION "${MySofa_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${MySofa_INCLUDE_DIR}")
endif()
mark_as_advanced(MySofa_INCLUDE_DIR MySofa_LIBRARY)
