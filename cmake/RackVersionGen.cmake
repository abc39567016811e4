# Writes the version source (run at every build by rack_version_source, cmake -P):
# the project version from CMake and `git describe` of the source tree when it is a
# git checkout with git installed (else empty). configure_file rewrites the file only
# when its text changes, so an unchanged tree recompiles nothing.
# Inputs: RACK_VERSION, RACK_SOURCE_DIR, RACK_VERSION_IN, RACK_VERSION_OUT.
set(RACK_GIT_DESCRIBE "")
find_program(RACK_GIT git)
if(RACK_GIT)
  execute_process(COMMAND ${RACK_GIT} -C ${RACK_SOURCE_DIR} describe --always --dirty --tags
                  OUTPUT_VARIABLE RACK_GIT_DESCRIBE OUTPUT_STRIP_TRAILING_WHITESPACE
                  ERROR_QUIET RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    set(RACK_GIT_DESCRIBE "")
  endif()
endif()
configure_file(${RACK_VERSION_IN} ${RACK_VERSION_OUT} @ONLY)
