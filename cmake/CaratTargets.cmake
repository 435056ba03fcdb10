#Helpers shared by carat's module targets.

#carat_add_module(NAME <name>[DEPS <targets...>][PRIVATE_DEPS <targets...>])
#Declares the library carat_ < name>(alias carat:: <name>, export name <name>)from
# <name> / src/*.cpp and <name>/src/io/*.cpp (file formats) with public headers in
# <name>/include/carat/<name>/ (and its io/ folder). PRIVATE_DEPS that only
# the sources include (header-only libraries) are wrapped in $<BUILD_INTERFACE:...> by the
# caller, so that the installed package does not ask consumers for them.
function(carat_add_module)
  cmake_parse_arguments(ARG "" "NAME" "DEPS;PRIVATE_DEPS" ${ARGN})
  file(GLOB _sources CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/src/*.cpp"
       "${CMAKE_CURRENT_SOURCE_DIR}/src/io/*.cpp")
  set(_target carat_${ARG_NAME})
  if(_sources)
    add_library(${_target} STATIC ${_sources})
    set_target_properties(${_target} PROPERTIES EXPORT_NAME ${ARG_NAME} OUTPUT_NAME carat_${ARG_NAME})
    target_include_directories(${_target} PUBLIC
      $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
      $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
    target_compile_features(${_target} PUBLIC cxx_std_20)
    target_link_libraries(${_target} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
    carat_set_warnings(${_target})
    if(CARAT_BUILD_FUZZERS)
      # libFuzzer's coverage feedback where the fuzzers aim: the file formats (src/io/) and base
      # (files, byte streams). Elsewhere its comparison hooks would only slow the code (the
      # tests built in the same tree run it) and its compile.
      file(GLOB _fuzzed CONFIGURE_DEPENDS "${CMAKE_CURRENT_SOURCE_DIR}/src/io/*.cpp")
      if(ARG_NAME STREQUAL "base")
        set(_fuzzed ${_sources})
      endif()
      if(_fuzzed)
        set_property(SOURCE ${_fuzzed} APPEND PROPERTY COMPILE_OPTIONS -fsanitize=fuzzer-no-link)
      endif()
    endif()
  else()
    # A module with headers only (or none yet).
    add_library(${_target} INTERFACE)
    set_target_properties(${_target} PROPERTIES EXPORT_NAME ${ARG_NAME})
    target_include_directories(${_target} INTERFACE
      $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
      $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
    target_link_libraries(${_target} INTERFACE ${ARG_DEPS})
  endif()
  add_library(carat::${ARG_NAME} ALIAS ${_target})
  # One export set per module, so that find_package(carat COMPONENTS ...) loads only the modules
  # asked for (and the ones they build on).
  install(TARGETS ${_target} EXPORT carat_${ARG_NAME}Targets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  install(EXPORT carat_${ARG_NAME}Targets NAMESPACE carat:: DESTINATION "${CARAT_CMAKE_DIR}")
  if(EXISTS "${CMAKE_CURRENT_SOURCE_DIR}/include")
    install(DIRECTORY "${CMAKE_CURRENT_SOURCE_DIR}/include/" DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  endif()
endfunction()

# Warnings on carat's own targets only; as errors with CARAT_WERROR (the scripts and CI set it).
function(carat_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra)
  # The code is clean under these with GCC; Clang's -Wconversion also checks signedness, which it
  # is not written for (the fuzzers build with Clang).
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    target_compile_options(${target} PRIVATE -Wshadow -Wconversion -Wpedantic)
  endif()
  if(CARAT_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
  if(CARAT_NATIVE)
    target_compile_options(${target} PRIVATE -march=native)
  endif()
  # A fuzzer tree without CARAT_SANITIZE: the sanitizers the fuzzers link with (libFuzzer's
  # coverage hooks go on the parsers' sources only: carat_add_module()).
  get_target_property(_type ${target} TYPE)
  if(CARAT_BUILD_FUZZERS AND NOT CARAT_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-sanitize-recover=all)
    if(NOT _type STREQUAL "STATIC_LIBRARY")
      target_link_options(${target} PRIVATE -fsanitize=address,undefined)
    endif()
  endif()
  if(CARAT_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer
                                             -fno-sanitize-recover=all)
    target_link_options(${target} PUBLIC -fsanitize=address,undefined)
  endif()
endfunction()
