# Installation (`cmake --install build [--prefix DIR]`, `make install`) and
# the Debian package (`make package`: cpack -G DEB).
#
#   bin/                         the processes and tools (ld-*)
#   include/ld/                  the libraries' public headers and the
#                                lcm-gen'd message headers
#   lib/                         the libraries (static), and
#   lib/cmake/landmark/          their CMake package: find_package(landmark)
#                                gives landmark::detector, landmark::qr_reader,
#                                landmark::tracker, landmark::landmark_msg,
#                                landmark::msgs, landmark::lcmtypes, landmark::core
#   lib/systemd/system/          the units of tools/systemd
#   lib/sysctl.d/                the socket receive buffer setting
#   share/landmark/              the message definitions (lcmtypes/*.lcm), the
#                                types jar for lcm-spy (java/), the example
#                                ld-run config and /etc/default/landmark
#                                template (examples/)
#   share/doc/landmark/          README and docs/
#
# Two components, two Debian packages: `runtime` (landmark: the programs and
# everything they use at run time) and `dev` (landmark-dev: libraries,
# headers and the CMake package, for building robot code of your own).
# `cmake --install` without --component installs both.
include(CMakePackageConfigHelpers)

# Programs a user runs (test-only helpers such as ld-publish-garbage stay out).
set(LD_INSTALL_PROGRAMS
  ld-camera ld-detector ld-tracker ld-qr-reader ld-run ld-play ld-view ld-dump
  ld-log-images ld-detect ld-generate ld-synth ld-eval ld-bench ld-bench-tracker ld-soak)
install(TARGETS ${LD_INSTALL_PROGRAMS} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
install(PROGRAMS ${CMAKE_BINARY_DIR}/bin/ld-spy ${CMAKE_BINARY_DIR}/bin/ld-bench-e2e
        DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
# A command in a private network namespace with multicast on loopback, for a
# program of one's own beside `ld-run --netns` (the README's
# scripts/netns-run.sh, which an installed user did not have: an API audit).
install(PROGRAMS scripts/netns-run.sh DESTINATION ${CMAKE_INSTALL_BINDIR} RENAME ld-netns-run COMPONENT runtime)

# Libraries, with the names they have in the package.
set_target_properties(ld_core PROPERTIES EXPORT_NAME core)
set_target_properties(ld_detector PROPERTIES EXPORT_NAME detector)
set_target_properties(ld_qr_reader PROPERTIES EXPORT_NAME qr_reader)
set_target_properties(ld_tracker PROPERTIES EXPORT_NAME tracker)
set_target_properties(ld_landmark_msg PROPERTIES EXPORT_NAME landmark_msg)
set_target_properties(ld_msgs PROPERTIES EXPORT_NAME msgs)
set_target_properties(ld_lcmtypes PROPERTIES EXPORT_NAME lcmtypes)
install(TARGETS ld_core ld_detector ld_qr_reader ld_tracker ld_landmark_msg ld_msgs ld_lcmtypes
        EXPORT landmarkTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# The command-line options header needs CLI11 and is the programs' own, as
# is the tracker's benchmark. (The tracker was not installed, though the
# README shows ld::Tracker to robot code: an API audit.)
install(DIRECTORY detector/include/ld qr_reader/include/ld tracker/include/ld lcmtypes/include/ld
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev
        FILES_MATCHING PATTERN "*.hpp" PATTERN "detector_options.hpp" EXCLUDE PATTERN "tracker_bench.hpp" EXCLUDE)
# lcm-gen's headers (lcmtypes/CMakeLists.txt writes them to cpp/ld/).
install(DIRECTORY ${CMAKE_BINARY_DIR}/lcmtypes/cpp/ld DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev
        FILES_MATCHING PATTERN "*.hpp")
install(EXPORT landmarkTargets NAMESPACE landmark::
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/landmark COMPONENT dev)
# (as detector/CMakeLists.txt links them: GBM only with the GLES backend)
set(LD_PACKAGE_HAS_GLES OFF)
set(LD_PACKAGE_HAS_GBM OFF)
if(LD_WITH_GLES AND LD_GLES_FOUND)
  set(LD_PACKAGE_HAS_GLES ON)
  if(LD_GBM_FOUND)
    set(LD_PACKAGE_HAS_GBM ON)
  endif()
endif()
configure_package_config_file(cmake/landmarkConfig.cmake.in
                              ${CMAKE_BINARY_DIR}/cmake/landmarkConfig.cmake
                              INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/landmark)
write_basic_package_version_file(${CMAKE_BINARY_DIR}/cmake/landmarkConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${CMAKE_BINARY_DIR}/cmake/landmarkConfig.cmake
              ${CMAKE_BINARY_DIR}/cmake/landmarkConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/landmark COMPONENT dev)

# Message definitions and the types jar (ld-spy finds it from bin/).
install(DIRECTORY lcmtypes/ DESTINATION ${CMAKE_INSTALL_DATADIR}/landmark/lcmtypes COMPONENT runtime
        FILES_MATCHING PATTERN "*.lcm" PATTERN "include" EXCLUDE PATTERN "src" EXCLUDE)
install(FILES ${CMAKE_BINARY_DIR}/java/ld_lcmtypes.jar DESTINATION ${CMAKE_INSTALL_DATADIR}/landmark/java
        COMPONENT runtime)

# systemd units, the sysctl setting, the site templates.
install(FILES tools/systemd/landmark.target tools/systemd/ld-camera.service
              tools/systemd/ld-detector.service tools/systemd/ld-tracker.service
              tools/systemd/ld-qr-reader.service tools/systemd/ld-run@.service
        DESTINATION lib/systemd/system COMPONENT runtime)
install(FILES tools/systemd/99-landmark-rmem.conf DESTINATION lib/sysctl.d COMPONENT runtime)
install(FILES tools/systemd/landmark.default tools/run/ld-run.example.json tools/run/ld-run.example.yaml
        DESTINATION ${CMAKE_INSTALL_DATADIR}/landmark/examples COMPONENT runtime)
install(FILES README.md DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/landmark COMPONENT runtime)
install(DIRECTORY docs/ DESTINATION ${CMAKE_INSTALL_DATADIR}/doc/landmark/docs COMPONENT runtime)

# The Debian packages: the two components above under /usr; the runtime's
# dependencies found by dpkg-shlibdeps from the programs' shared libraries,
# the dev package's the development packages its CMake package finds.
set(CPACK_GENERATOR DEB)
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_COMPONENTS_ALL runtime dev)
set(CPACK_DEBIAN_ENABLE_COMPONENT_DEPENDS ON)
set(CPACK_COMPONENT_DEV_DEPENDS runtime)  # landmark-dev: Depends landmark (= version)
set(CPACK_PACKAGE_NAME landmark)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_PACKAGE_CONTACT "landmark maintainers <landmark@localhost>")
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY
    "Colour landmark detection, tracking and QR reading for mobile robots over LCM")
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_NAME landmark)
set(CPACK_COMPONENT_RUNTIME_DESCRIPTION
    "Colour landmark detection, tracking and QR reading for mobile robots over LCM: the processes and tools")
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SECTION science)
set(CPACK_DEBIAN_RUNTIME_PACKAGE_SHLIBDEPS ON)
# ld-spy runs lcm-spy's Java classes; ld-bench-e2e uses jq; ld-netns-run, ip. The GLES backend
# needs an EGL driver (Mesa's, or a GPU vendor's). ld-generate's PNG labels
# want DejaVu Sans (without it, ASCII alone).
set(CPACK_DEBIAN_RUNTIME_PACKAGE_DEPENDS
    "default-jre-headless | java-runtime-headless, liblcm-java, libjchart2d-java, jq, iproute2")
set(CPACK_DEBIAN_RUNTIME_PACKAGE_RECOMMENDS "libegl-mesa0, libgl1-mesa-dri, liblcm-bin, fonts-dejavu-core")
set(CPACK_DEBIAN_DEV_PACKAGE_NAME landmark-dev)
set(CPACK_DEBIAN_DEV_PACKAGE_SECTION libdevel)
set(CPACK_COMPONENT_DEV_DESCRIPTION
    "Colour landmark detection: static libraries, headers and CMake package (find_package(landmark))")
# What landmarkConfig.cmake finds (find_dependency / pkg-config; lcm.pc
# requires glib, which liblcm-dev does not pull in), and a compiler.
set(LD_DEV_DEPENDS "libopencv-dev, liblcm-dev, libglib2.0-dev, libzbar-dev, libjpeg-dev, pkg-config, g++ | c++-compiler")
if(LD_PACKAGE_HAS_GLES)
  string(APPEND LD_DEV_DEPENDS ", libegl-dev, libgles-dev")
endif()
if(LD_PACKAGE_HAS_GBM)
  string(APPEND LD_DEV_DEPENDS ", libgbm-dev")
endif()
set(CPACK_DEBIAN_DEV_PACKAGE_DEPENDS "${LD_DEV_DEPENDS}")
# postinst: the receive-buffer setting applied now (when it raises the
# limit), daemon-reload, running units restarted on an upgrade; prerm: the
# units stopped on removal; postrm: daemon-reload.
set(CPACK_DEBIAN_RUNTIME_PACKAGE_CONTROL_EXTRA ${PROJECT_SOURCE_DIR}/cmake/debian/postinst
                                              ${PROJECT_SOURCE_DIR}/cmake/debian/prerm
                                              ${PROJECT_SOURCE_DIR}/cmake/debian/postrm)
set(CPACK_DEBIAN_PACKAGE_CONTROL_STRICT_PERMISSION ON)
include(CPack)
