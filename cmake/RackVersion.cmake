# rack::version: the header rack/version.h (rack::kVersion, rack::kGitDescribe) that
# every tool's --version prints. Regenerated at each build (git describe changes with
# every commit) but rewritten only when its text changes.
set(RACK_VERSION_DIR ${CMAKE_BINARY_DIR}/generated/version)
add_custom_target(rack_version_header
  COMMAND ${CMAKE_COMMAND} -DRACK_VERSION=${PROJECT_VERSION} -DRACK_SOURCE_DIR=${CMAKE_SOURCE_DIR}
          -DRACK_VERSION_IN=${CMAKE_CURRENT_LIST_DIR}/version.h.in
          -DRACK_VERSION_OUT=${RACK_VERSION_DIR}/rack/version.h
          -P ${CMAKE_CURRENT_LIST_DIR}/RackVersionGen.cmake
  BYPRODUCTS ${RACK_VERSION_DIR}/rack/version.h
  COMMENT "rack/version.h (git describe)")
add_library(rack_version INTERFACE)
target_include_directories(rack_version INTERFACE ${RACK_VERSION_DIR})
add_dependencies(rack_version rack_version_header)
add_library(rack::version ALIAS rack_version)
