# `cmake --install` exports softgi::core (and later targets) for find_package(softgi).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

install(TARGETS softgi_core softgi_io softgi_reference softgi_cpu softgi_accum softgi_techniques softgi_techniques_vulkan softgi_options EXPORT softgiTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/core/include/softgi ${PROJECT_SOURCE_DIR}/backends/include/softgi
  ${PROJECT_SOURCE_DIR}/techniques/include/softgi DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
if(TARGET softgi)
  install(TARGETS softgi RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
if(TARGET softgi-viewer)
  install(TARGETS softgi-viewer RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
install(EXPORT softgiTargets NAMESPACE softgi:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/softgi)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/softgiConfig.cmake.in
  ${PROJECT_BINARY_DIR}/softgiConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/softgi)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/softgiConfigVersion.cmake COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/softgiConfig.cmake ${PROJECT_BINARY_DIR}/softgiConfigVersion.cmake
  DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/softgi)
