# Installing certislam: the command and certislam-robot (one back-end-only robot, without PCL or
# OpenVDB), the algorithm libraries with their headers and a CMake package
# (find_package(certislam) -> certislam::slam_core, certislam::certify, ...), and a Debian package
# of it all (cpack -G DEB).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(CERTISLAM_EXPORTED
  slam_core slam_io_base slam_io slam_sim slam_frontend slam_backend slam_mapping slam_eval slam
  certify certify_distributed pipeline_rounds pipeline pcl_io zstd cholmod)
set(exported_targets)
foreach(name ${CERTISLAM_EXPORTED})
  set(target certislam_${name})
  set_target_properties(${target} PROPERTIES EXPORT_NAME ${name})
  add_library(certislam::${name} ALIAS ${target})
  list(APPEND exported_targets ${target})
endforeach()
install(TARGETS ${exported_targets} EXPORT certislamTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/certislam)
install(TARGETS certislam certislam-robot RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
install(DIRECTORY ${PROJECT_SOURCE_DIR}/slam ${PROJECT_SOURCE_DIR}/certify
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/certislam FILES_MATCHING PATTERN "*.h")
install(DIRECTORY ${PROJECT_SOURCE_DIR}/deploy/configs
        DESTINATION ${CMAKE_INSTALL_DATADIR}/certislam)

set(config_dir ${CMAKE_INSTALL_LIBDIR}/cmake/certislam)
install(EXPORT certislamTargets NAMESPACE certislam:: DESTINATION ${config_dir})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/certislamConfig.cmake.in
  ${PROJECT_BINARY_DIR}/certislamConfig.cmake INSTALL_DESTINATION ${config_dir})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/certislamConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/certislamConfig.cmake
              ${PROJECT_BINARY_DIR}/certislamConfigVersion.cmake DESTINATION ${config_dir})

# Debian package: `cpack -G DEB` in the build folder.
set(CPACK_GENERATOR DEB)
set(CPACK_PACKAGE_NAME certislam)
set(CPACK_PACKAGE_CONTACT "certislam maintainers")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Decentralized multi-robot LiDAR SLAM with a certifiably optimal pose-graph back end")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)  # runtime libraries from dpkg-shlibdeps
set(CPACK_DEBIAN_PACKAGE_SECTION science)
include(CPack)
