# CPack: a Debian package of the installed tree (`cpack -G DEB` in the build folder;
# README "Deploying on a robot"). Run-time dependencies are Debian package names:
# dpkg-shlibdeps derives them from the programs' shared libraries, and the -dev
# packages that the SDK's static libraries link against are Recommends (needed to
# build out-of-tree tools against rack::client, not to run rackd or a plug-in).
set(CPACK_PACKAGE_NAME rack-rt)
set(CPACK_PACKAGE_VENDOR "RACK-RT")
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_DESCRIPTION_SUMMARY "RACK-RT real-time component executor for robots, tools and SDK")
set(CPACK_PACKAGE_DESCRIPTION "rackd runs the component classes a host file names with SCHED_FIFO tasks on \
locked memory; rackctl, gdos and rack-gui talk to them over TiMS/LCM. Includes the headers, static \
libraries and CMake package (find_package(rack)) for component classes built outside the tree, and \
the systemd unit rackd@.service (one host file per instance: /etc/rack/NAME.yaml).")
set(CPACK_PACKAGE_CONTACT "RACK-RT maintainers <rack-rt@localhost>")
# The configured prefix (the unit's ExecStart names rackd there): -DCMAKE_INSTALL_PREFIX=/usr
# for a package that follows Debian's layout.
set(CPACK_PACKAGING_INSTALL_PREFIX ${CMAKE_INSTALL_PREFIX})
set(CPACK_GENERATOR DEB)
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)
set(CPACK_DEBIAN_PACKAGE_SECTION misc)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
# nodejs: rack-foxglove (the Foxglove bridge, MCAP recorder and player) runs on node.
set(CPACK_DEBIAN_PACKAGE_RECOMMENDS
    "cmake, g++, liblcm-dev, libzstd-dev, libsodium-dev, libyaml-dev, libyaml-cpp-dev, pkg-config, nodejs")
set(CPACK_DEBIAN_PACKAGE_SUGGESTS "rt-tests, can-utils")
include(CPack)
