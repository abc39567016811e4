# rack::version: rack_version() and print_version() (tools/version/rack/version.h) that
# every tool's --version prints. Its one source file is generated at each build from
# tools/version/version.cpp.in (git describe changes with every commit) and rewritten
# only when its text changes, so a commit recompiles that file alone.
set(RACK_VERSION_CPP ${CMAKE_BINARY_DIR}/generated/version_src/version.cpp)
add_custom_target(rack_version_source
  COMMAND ${CMAKE_COMMAND} -DRACK_VERSION=${PROJECT_VERSION} -DRACK_SOURCE_DIR=${CMAKE_SOURCE_DIR}
          -DRACK_VERSION_IN=${CMAKE_SOURCE_DIR}/tools/version/version.cpp.in
          -DRACK_VERSION_OUT=${RACK_VERSION_CPP}
          -P ${CMAKE_CURRENT_LIST_DIR}/RackVersionGen.cmake
  BYPRODUCTS ${RACK_VERSION_CPP}
  COMMENT "version.cpp (git describe)")
add_library(rack_version STATIC ${RACK_VERSION_CPP})
target_include_directories(rack_version PUBLIC ${CMAKE_SOURCE_DIR}/tools/version)
add_dependencies(rack_version rack_version_source)
rack_set_warnings(rack_version)
add_library(rack::version ALIAS rack_version)
