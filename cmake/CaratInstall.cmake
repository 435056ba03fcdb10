# Installs carat as a CMake package: find_package(carat CONFIG) then link carat::carat, or
# find_package(carat CONFIG COMPONENTS solver ...) then link the modules asked for. Each module's
# targets are exported by carat_add_module; this file adds the umbrella target and the config.
include(CMakePackageConfigHelpers)

install(TARGETS carat EXPORT caratTargets)
install(EXPORT caratTargets NAMESPACE carat:: DESTINATION "${CARAT_CMAKE_DIR}")
configure_package_config_file("${CMAKE_CURRENT_SOURCE_DIR}/cmake/caratConfig.cmake.in"
  "${CMAKE_CURRENT_BINARY_DIR}/caratConfig.cmake" INSTALL_DESTINATION "${CARAT_CMAKE_DIR}")
write_basic_package_version_file("${CMAKE_CURRENT_BINARY_DIR}/caratConfigVersion.cmake"
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES "${CMAKE_CURRENT_BINARY_DIR}/caratConfig.cmake"
              "${CMAKE_CURRENT_BINARY_DIR}/caratConfigVersion.cmake"
              "${CMAKE_CURRENT_SOURCE_DIR}/cmake/FindCHOLMOD.cmake"
        DESTINATION "${CARAT_CMAKE_DIR}")
