# Everything `cmake --install` and `cpack` do (issue 19, item 5), in one place:
#   bin/            rackd, rackctl, gdos, rack-gui, rack-backtrace, rack-devsim,
#                   rack-foxglove (a shell script: node on share/rack/foxglove)
#   include/rack/   the public headers (rt, tims, client, core, interfaces)
#   lib/            the libraries (rack::rt, rack::tims, rack::client, rack::core;
#                   rack::interfaces is header only)
#   lib/rack/plugins/        component-class plug-ins (RACK_INSTALL_PLUGINDIR)
#   lib/cmake/rack/          rackConfig.cmake, rackConfigVersion.cmake, rackTargets.cmake,
#                            RackPlugin.cmake (rack_add_plugin), rack_plugin_abi_note.cpp
#                            (the ABI stamp of the installed headers, rack/core/plugin_abi.h)
#   share/rack/configs/      the commented example host files
#   share/rack/examples/     examples/out_of_tree_class
#   share/rack-gui/web/      rack-gui's front end (when built: tools/gui/web, npm run build)
#   share/rack/foxglove/     rack-foxglove (tools/foxglove: the scripts and their npm
#                            packages, when npm ci ran); bin/rack-foxglove runs it with node
#   lib/systemd/system/      rackd@.service (one host file per instance: /etc/rack/<i>.yaml)
#   share/doc/rack_rt/       README.md
# Install components: Runtime (programs, plug-ins, unit, configs), Development (headers,
# libraries, CMake package, examples), Gui (rack-gui and its front end, rack-foxglove).
# Included at the end of the top CMakeLists.txt, after every target exists.
include(CMakePackageConfigHelpers)

set(RACK_INSTALL_PLUGINDIR ${CMAKE_INSTALL_LIBDIR}/rack/plugins CACHE STRING
    "Where component-class plug-ins are installed (relative to the prefix)")
set(RACK_INSTALL_CONFIGDIR ${CMAKE_INSTALL_DATADIR}/rack/configs)
set(RACK_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/rack)

# Programs.
install(TARGETS rackd rackctl gdos rack-backtrace rack-devsim
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT Runtime)
install(TARGETS rack-gui RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT Gui)
# The built front end: rack-gui serves <prefix>/share/rack-gui/web when the source
# tree's web/dist is not there (OPTIONAL: absent until npm built it).
install(DIRECTORY ${PROJECT_SOURCE_DIR}/tools/gui/web/dist/ DESTINATION ${CMAKE_INSTALL_DATADIR}/rack-gui/web
        COMPONENT Gui OPTIONAL)
# rack-foxglove (Gui): the scripts, their lock file and the npm packages `npm ci` put in
# tools/foxglove/node_modules (OPTIONAL: absent until scripts/setup.sh ran; the
# installed bin/rack-foxglove then says so), and bin/rack-foxglove, which finds them
# relative to itself (a relocated tree or a package works).
set(RACK_FOXGLOVE_SHARE ${CMAKE_INSTALL_DATADIR}/rack/foxglove)
file(RELATIVE_PATH RACK_FOXGLOVE_FROM_BIN ${CMAKE_INSTALL_PREFIX}/${CMAKE_INSTALL_BINDIR}
     ${CMAKE_INSTALL_PREFIX}/${RACK_FOXGLOVE_SHARE})
configure_file(${PROJECT_SOURCE_DIR}/tools/foxglove/rack-foxglove.sh.in ${PROJECT_BINARY_DIR}/rack-foxglove @ONLY)
install(PROGRAMS ${PROJECT_BINARY_DIR}/rack-foxglove DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT Gui)
install(FILES ${PROJECT_SOURCE_DIR}/tools/foxglove/rack-foxglove.mjs ${PROJECT_SOURCE_DIR}/tools/foxglove/package.json
              ${PROJECT_SOURCE_DIR}/tools/foxglove/package-lock.json
        DESTINATION ${RACK_FOXGLOVE_SHARE} COMPONENT Gui)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/tools/foxglove/lib DESTINATION ${RACK_FOXGLOVE_SHARE} COMPONENT Gui)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/tools/foxglove/node_modules DESTINATION ${RACK_FOXGLOVE_SHARE}
        COMPONENT Gui OPTIONAL)

# Plug-ins: every target in RACK_PLUGIN_TARGETS (rack_add_plugin targets of the tree).
install(DIRECTORY DESTINATION ${RACK_INSTALL_PLUGINDIR} COMPONENT Runtime)
if(RACK_PLUGIN_TARGETS)
  install(TARGETS ${RACK_PLUGIN_TARGETS} LIBRARY DESTINATION ${RACK_INSTALL_PLUGINDIR} COMPONENT Runtime)
endif()

# Example host files and the systemd unit.
install(DIRECTORY ${PROJECT_SOURCE_DIR}/configs/ DESTINATION ${RACK_INSTALL_CONFIGDIR} COMPONENT Runtime)
# The unit names rackd by its full path: configure with -DCMAKE_INSTALL_PREFIX=/usr for
# a package (cmake/RackPackage.cmake packages that prefix).
configure_file(${PROJECT_SOURCE_DIR}/scripts/systemd/rackd@.service.in
               ${PROJECT_BINARY_DIR}/systemd/rackd@.service @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/systemd/rackd@.service
        DESTINATION lib/systemd/system COMPONENT Runtime)  # /usr/lib/systemd/system for /usr

# The README (the unit's Documentation=).
install(FILES ${PROJECT_SOURCE_DIR}/README.md DESTINATION ${CMAKE_INSTALL_DOCDIR} COMPONENT Runtime)

# Headers: one tree, rack/<area>/.
foreach(_dir core/rt/include tims/include client/include core/include components/interfaces/include)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${_dir}/rack DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
          COMPONENT Development FILES_MATCHING PATTERN "*.h")
endforeach()

# Headers only, for plug-ins (cmake/RackPlugin.cmake says why they link no library).
add_library(rack_plugin_api INTERFACE)
add_library(rack::plugin_api ALIAS rack_plugin_api)
set_target_properties(rack_plugin_api PROPERTIES EXPORT_NAME plugin_api)
target_include_directories(rack_plugin_api INTERFACE $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>
  $<BUILD_INTERFACE:$<TARGET_PROPERTY:rack_core,INTERFACE_INCLUDE_DIRECTORIES>>)
target_compile_features(rack_plugin_api INTERFACE cxx_std_20)

# Libraries and the CMake package.
# Their headers are C++20: users of the exported targets compile as C++20 too.
foreach(_lib rack_rt rack_tims rack_client rack_core)
  target_compile_features(${_lib} PUBLIC cxx_std_20)
endforeach()
target_compile_features(rack_interfaces INTERFACE cxx_std_20)
set_target_properties(rack_rt PROPERTIES EXPORT_NAME rt)
set_target_properties(rack_tims PROPERTIES EXPORT_NAME tims)
set_target_properties(rack_core PROPERTIES EXPORT_NAME core)
set_target_properties(rack_interfaces PROPERTIES EXPORT_NAME interfaces)
install(TARGETS rack_rt rack_tims rack_client rack_core rack_interfaces rack_plugin_api
        EXPORT rackTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT Development
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT Runtime
        INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
# The other shared libraries rackd and the plug-ins load (rackd's RUNPATH: $ORIGIN/../lib).
foreach(_lib rack_maps rack_devices rack_components)
  get_target_property(_type ${_lib} TYPE)
  if(_type STREQUAL "SHARED_LIBRARY")
    install(TARGETS ${_lib} LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT Runtime)
  endif()
endforeach()
install(EXPORT rackTargets NAMESPACE rack:: DESTINATION ${RACK_INSTALL_CMAKEDIR} COMPONENT Development)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/rackConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/rackConfig.cmake
                              INSTALL_DESTINATION ${RACK_INSTALL_CMAKEDIR}
                              PATH_VARS RACK_INSTALL_PLUGINDIR RACK_INSTALL_CONFIGDIR)
write_basic_package_version_file(${PROJECT_BINARY_DIR}/rackConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/rackConfig.cmake ${PROJECT_BINARY_DIR}/rackConfigVersion.cmake
              ${PROJECT_SOURCE_DIR}/cmake/RackPlugin.cmake ${RACK_PLUGIN_ABI_NOTE_SOURCE}
        DESTINATION ${RACK_INSTALL_CMAKEDIR} COMPONENT Development)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/examples/ DESTINATION ${CMAKE_INSTALL_DATADIR}/rack/examples
        COMPONENT Development)

include(RackPackage)
