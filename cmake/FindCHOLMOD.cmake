# FindCHOLMOD
# -----------
# Finds SuiteSparse's CHOLMOD (Debian's libsuitesparse-dev ships no CMake package for it).
#
# Imported target: CHOLMOD::CHOLMOD
# Variables: CHOLMOD_FOUND, CHOLMOD_INCLUDE_DIR, CHOLMOD_LIBRARY, CHOLMOD_VERSION
#
# CHOLMOD's own dependencies (AMD, CAMD, COLAMD, CCOLAMD, SuiteSparse_config, BLAS, LAPACK)
# are linked through the shared library; the AMD library is added explicitly because carat
# calls amd_l_order for its block ordering, and the BLAS and LAPACK (the ones CHOLMOD uses) because
# carat's sparse inverse runs its dense products through them.

find_path(CHOLMOD_INCLUDE_DIR NAMES cholmod.h PATH_SUFFIXES suitesparse)
find_library(CHOLMOD_LIBRARY NAMES cholmod)
find_library(CHOLMOD_AMD_LIBRARY NAMES amd)
find_library(CHOLMOD_SUITESPARSECONFIG_LIBRARY NAMES suitesparseconfig)
find_library(CHOLMOD_BLAS_LIBRARY NAMES blas)
find_library(CHOLMOD_LAPACK_LIBRARY NAMES lapack)

if(CHOLMOD_INCLUDE_DIR AND EXISTS "${CHOLMOD_INCLUDE_DIR}/cholmod_core.h")
  file(STRINGS "${CHOLMOD_INCLUDE_DIR}/cholmod_core.h" _cholmod_version_lines
       REGEX "#define CHOLMOD_(MAIN|SUB|SUBSUB)_VERSION[ \t]+[0-9]+")
  foreach(_part MAIN SUB SUBSUB)
    string(REGEX REPLACE ".*#define CHOLMOD_${_part}_VERSION[ \t]+([0-9]+).*" "\\1"
           _cholmod_${_part} "${_cholmod_version_lines}")
  endforeach()
  set(CHOLMOD_VERSION "${_cholmod_MAIN}.${_cholmod_SUB}.${_cholmod_SUBSUB}")
endif()

include(FindPackageHandleStandardArgs)
find_package_handle_standard_args(CHOLMOD
  REQUIRED_VARS CHOLMOD_LIBRARY CHOLMOD_AMD_LIBRARY CHOLMOD_SUITESPARSECONFIG_LIBRARY
                CHOLMOD_BLAS_LIBRARY CHOLMOD_LAPACK_LIBRARY CHOLMOD_INCLUDE_DIR
  VERSION_VAR CHOLMOD_VERSION)

if(CHOLMOD_FOUND AND NOT TARGET CHOLMOD::CHOLMOD)
  add_library(CHOLMOD::CHOLMOD UNKNOWN IMPORTED)
  set_target_properties(CHOLMOD::CHOLMOD PROPERTIES
    IMPORTED_LOCATION "${CHOLMOD_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${CHOLMOD_INCLUDE_DIR}"
    INTERFACE_LINK_LIBRARIES
      "${CHOLMOD_AMD_LIBRARY};${CHOLMOD_SUITESPARSECONFIG_LIBRARY};${CHOLMOD_LAPACK_LIBRARY};${CHOLMOD_BLAS_LIBRARY}")
endif()
mark_as_advanced(CHOLMOD_INCLUDE_DIR CHOLMOD_LIBRARY CHOLMOD_AMD_LIBRARY CHOLMOD_SUITESPARSECONFIG_LIBRARY
                 CHOLMOD_BLAS_LIBRARY CHOLMOD_LAPACK_LIBRARY)
